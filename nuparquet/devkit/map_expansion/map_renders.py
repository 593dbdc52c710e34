"""The renderers of the devkit's `NuScenesMapExplorer`: its matplotlib figures, statement for statement, over the
converted map (the explorer's `extract_polygon`, `get_records_in_patch`, ... of `map_explorer`).

One change: the devkit draws polygons with `descartes.PolygonPatch`, which raises IndexError under shapely 2
(`asarray(polygon.exterior)` is no longer its coordinates: devkit issues #870, #1180), so `render_record`,
`render_layers` of polygon layers, `render_map_patch`, `render_map_in_image`, `render_egoposes_on_fancy_map` and
`render_next_roads` fail there. Here `polygon_patch` builds the same matplotlib path (each ring a MOVETO then
LINETOs, holes after their exterior) from the rings' coordinates. The devkit sets pyplot's 'seaborn-v0_8-whitegrid'
style when imported; here it is set when a figure is first drawn, so programs that never render keep their style.
The figures are returned (fig, axes) as the devkit's; `plt.savefig` where it writes `out_path`.

Longer than our ~300-line norm on purpose: it is the devkit's figure code statement for statement, so the pixels
are its pixels.
"""

from __future__ import annotations

import random
from typing import List, Tuple, Union

import numpy as np

STYLE = 'seaborn-v0_8-whitegrid'  # the devkit's map_api sets it at import


def _pyplot():
    import matplotlib.pyplot as plt

    if not getattr(_pyplot, "styled", False):
        plt.style.use(STYLE)
        _pyplot.styled = True
    return plt


def polygon_patch(polygon, **kwargs):
    """descartes' `PolygonPatch` for shapely 2: a matplotlib PathPatch of a Polygon or MultiPolygon, the path
    descartes builds (each polygon's exterior, then its holes; each ring a MOVETO and LINETOs)."""
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path

    if polygon.geom_type == 'Polygon':
        polygons = [polygon]
    elif polygon.geom_type == 'MultiPolygon':
        polygons = list(polygon.geoms)
    else:
        raise ValueError("A polygon or multi-polygon representation is required")

    def coding(n):
        vals = np.ones(n, dtype=Path.code_type) * Path.LINETO
        vals[0] = Path.MOVETO
        return vals

    rings = [[p.exterior] + list(p.interiors) for p in polygons]
    vertices = np.concatenate([np.concatenate([np.asarray(r.coords)[:, :2] for r in t]) for t in rings])
    codes = np.concatenate([np.concatenate([coding(len(r.coords)) for r in t]) for t in rings])
    return PathPatch(Path(vertices, codes), **kwargs)


class MapRenders:
    """The explorer's figures (mixed into `NuScenesMapExplorer`)."""

    def render_centerlines(self, resolution_meters: float, figsize: Union[None, float, Tuple[float, float]] = None,
                           bitmap=None):
        """Every lane's and lane connector's centreline (one pyplot line each)."""
        plt = _pyplot()
        pose_lists = self.map_api.discretize_centerlines(resolution_meters)

        fig = plt.figure(figsize=self._get_figsize(figsize))
        ax = fig.add_axes([0, 0, 1, 1 / self.canvas_aspect_ratio])

        if bitmap is not None:
            bitmap.render(self.map_api.canvas_edge, ax)

        for pose_list in pose_lists:
            if len(pose_list) > 0:
                plt.plot(pose_list[:, 0], pose_list[:, 1])

        return fig, ax

    def render_map_mask(self, patch_box: Tuple[float, float, float, float], patch_angle: float,
                        layer_names: List[str], canvas_size: Tuple[int, int], figsize: Tuple[int, int],
                        n_row: int = 2):
        """`get_map_mask`'s masks in a grid of `n_row` rows."""
        import matplotlib.gridspec as gridspec

        plt = _pyplot()
        if layer_names is None:
            layer_names = self.map_api.non_geometric_layers

        map_mask = self.get_map_mask(patch_box, patch_angle, layer_names, canvas_size)

        # If no canvas_size is specified, retrieve the default from the output of get_map_mask.
        if canvas_size is None:
            canvas_size = map_mask.shape[1:]

        fig = plt.figure(figsize=figsize)
        ax = fig.add_axes([0, 0, 1, 1])
        ax.set_xlim(0, canvas_size[1])
        ax.set_ylim(0, canvas_size[0])

        n_col = len(map_mask) // n_row
        gs = gridspec.GridSpec(n_row, n_col)
        gs.update(wspace=0.025, hspace=0.05)
        for i in range(len(map_mask)):
            r = i // n_col
            c = i - r * n_col
            subax = plt.subplot(gs[r, c])
            subax.imshow(map_mask[i], origin='lower')
            subax.text(canvas_size[0] * 0.5, canvas_size[1] * 1.1, layer_names[i])
            subax.grid(False)

        return fig, fig.axes

    def render_record(self, layer_name: str, token: str, alpha: float = 0.5,
                      figsize: Union[None, float, Tuple[float, float]] = None, other_layers: List[str] = None,
                      bitmap=None):
        """One record in the whole map and close up, with `other_layers` (default the representative ones)."""
        from matplotlib.patches import Rectangle
        from mpl_toolkits.axes_grid1.inset_locator import mark_inset

        plt = _pyplot()
        if other_layers is None:
            other_layers = list(self.representative_layers)

        for other_layer in other_layers:
            if other_layer not in self.map_api.non_geometric_layers:
                raise ValueError("{} is not a non geometric layer".format(layer_name))

        x1, y1, x2, y2 = self.map_api.get_bounds(layer_name, token)

        local_width = x2 - x1
        local_height = y2 - y1
        assert local_height > 0, 'Error: Map has 0 height!'
        local_aspect_ratio = local_width / local_height

        # We obtained the values 0.65 and 0.66 by trials.
        fig = plt.figure(figsize=self._get_figsize(figsize))
        global_ax = fig.add_axes([0, 0, 0.65, 0.65 / self.canvas_aspect_ratio])
        local_ax = fig.add_axes([0.66, 0.66 / self.canvas_aspect_ratio, 0.34, 0.34 / local_aspect_ratio])

        # To make sure the sequence of the layer overlays is always consistent after typesetting set().
        random.seed('nutonomy')

        if bitmap is not None:
            bitmap.render(self.map_api.canvas_edge, global_ax)
            bitmap.render(self.map_api.canvas_edge, local_ax)

        layer_names = other_layers + [layer_name]
        layer_names = list(set(layer_names))

        for layer in layer_names:
            self._render_layer(global_ax, layer, alpha)

        for layer in layer_names:
            self._render_layer(local_ax, layer, alpha)

        if layer_name == 'drivable_area':
            # Bad output aesthetically if we add spacing between the objects and the axes for drivable area.
            local_ax_xlim = (x1, x2)
            local_ax_ylim = (y1, y2)
        else:
            # Add some spacing between the object and the axes.
            local_ax_xlim = (x1 - local_width / 3, x2 + local_width / 3)
            local_ax_ylim = (y1 - local_height / 3, y2 + local_height / 3)

            # Draws the rectangular patch on the local_ax.
            local_ax.add_patch(Rectangle((x1, y1), local_width, local_height, linestyle='-.', color='red', fill=False,
                                         lw=2))

        local_ax.set_xlim(*local_ax_xlim)
        local_ax.set_ylim(*local_ax_ylim)
        local_ax.set_title('Local View')

        global_ax.set_xlim(self.canvas_min_x, self.canvas_max_x)
        global_ax.set_ylim(self.canvas_min_y, self.canvas_max_y)
        global_ax.set_title('Global View')
        global_ax.legend()

        # Adds the zoomed in effect to the plot.
        mark_inset(global_ax, local_ax, loc1=2, loc2=4)

        return fig, (global_ax, local_ax)

    def render_layers(self, layer_names: List[str], alpha: float,
                      figsize: Union[None, float, Tuple[float, float]], tokens: List[str] = None, bitmap=None):
        """Layers over the whole map (only `tokens` when given)."""
        plt = _pyplot()
        fig = plt.figure(figsize=self._get_figsize(figsize))
        ax = fig.add_axes([0, 0, 1, 1 / self.canvas_aspect_ratio])

        ax.set_xlim(self.canvas_min_x, self.canvas_max_x)
        ax.set_ylim(self.canvas_min_y, self.canvas_max_y)

        if bitmap is not None:
            bitmap.render(self.map_api.canvas_edge, ax)

        layer_names = list(set(layer_names))
        for layer_name in layer_names:
            self._render_layer(ax, layer_name, alpha, tokens)

        ax.legend()

        return fig, ax

    def render_map_patch(self, box_coords: Tuple[float, float, float, float], layer_names: List[str] = None,
                         alpha: float = 0.5, figsize: Tuple[float, float] = (15, 15),
                         render_egoposes_range: bool = True, render_legend: bool = True, bitmap=None):
        """The layers over the box (x_min, y_min, x_max, y_max) plus margins, its outline and size, a legend."""
        from matplotlib.patches import Rectangle

        plt = _pyplot()
        x_min, y_min, x_max, y_max = box_coords

        if layer_names is None:
            layer_names = self.map_api.non_geometric_layers

        fig = plt.figure(figsize=figsize)

        local_width = x_max - x_min
        local_height = y_max - y_min
        assert local_height > 0, 'Error: Map patch has 0 height!'
        local_aspect_ratio = local_width / local_height

        ax = fig.add_axes([0, 0, 1, 1 / local_aspect_ratio])

        if bitmap is not None:
            bitmap.render(self.map_api.canvas_edge, ax)

        for layer_name in layer_names:
            self._render_layer(ax, layer_name, alpha)

        x_margin = np.minimum(local_width / 4, 50)
        y_margin = np.minimum(local_height / 4, 10)
        ax.set_xlim(x_min - x_margin, x_max + x_margin)
        ax.set_ylim(y_min - y_margin, y_max + y_margin)

        if render_egoposes_range:
            ax.add_patch(Rectangle((x_min, y_min), local_width, local_height, fill=False, linestyle='-.', color='red',
                                   lw=2))
            ax.text(x_min + local_width / 100, y_min + local_height / 2, "%g m" % local_height,
                    fontsize=14, weight='bold')
            ax.text(x_min + local_width / 2, y_min + local_height / 100, "%g m" % local_width,
                    fontsize=14, weight='bold')

        if render_legend:
            ax.legend(frameon=True, loc='upper right')

        return fig, ax

    def render_map_in_image(self, nusc, sample_token: str, camera_channel: str = 'CAM_FRONT', alpha: float = 0.3,
                            patch_radius: float = 10000, min_polygon_area: float = 1000,
                            render_behind_cam: bool = True, render_outside_im: bool = True,
                            layer_names: List[str] = None, verbose: bool = True, out_path: str = None):
        """A camera image of sample `sample_token` with the polygon layers projected into it (`nusc`: a devkit
        `NuScenes` or `nuparquet.devkit.NuScenes` whose images are on disk)."""
        from PIL import Image
        from pyquaternion import Quaternion
        from shapely.geometry import Polygon

        from nuparquet.devkit.utils.geometry_utils import view_points

        plt = _pyplot()
        near_plane = 1e-8

        if verbose:
            print('Warning: Note that the projections are not always accurate as the localization is in 2d.')

        # Default layers.
        if layer_names is None:
            layer_names = ['road_segment', 'lane', 'ped_crossing', 'walkway', 'stop_line', 'carpark_area']

        # Check layers whether we can render them.
        for layer_name in layer_names:
            assert layer_name in self.map_api.non_geometric_polygon_layers, \
                'Error: Can only render non-geometry polygons: %s' % layer_names

        # Check that NuScenesMap was loaded for the correct location.
        sample_record = nusc.get('sample', sample_token)
        scene_record = nusc.get('scene', sample_record['scene_token'])
        log_record = nusc.get('log', scene_record['log_token'])
        log_location = log_record['location']
        assert self.map_api.map_name == log_location, \
            'Error: NuScenesMap loaded for location %s, should be %s!' % (self.map_api.map_name, log_location)

        # Grab the front camera image and intrinsics.
        cam_token = sample_record['data'][camera_channel]
        cam_record = nusc.get('sample_data', cam_token)
        cam_path = nusc.get_sample_data_path(cam_token)
        im = Image.open(cam_path)
        im_size = im.size
        cs_record = nusc.get('calibrated_sensor', cam_record['calibrated_sensor_token'])
        cam_intrinsic = np.array(cs_record['camera_intrinsic'])

        # Retrieve the current map.
        poserecord = nusc.get('ego_pose', cam_record['ego_pose_token'])
        ego_pose = poserecord['translation']
        box_coords = (
            ego_pose[0] - patch_radius,
            ego_pose[1] - patch_radius,
            ego_pose[0] + patch_radius,
            ego_pose[1] + patch_radius,
        )
        records_in_patch = self.get_records_in_patch(box_coords, layer_names, 'intersect')

        # Init axes.
        fig = plt.figure(figsize=(9, 16))
        ax = fig.add_axes([0, 0, 1, 1])
        ax.set_xlim(0, im_size[0])
        ax.set_ylim(0, im_size[1])
        ax.imshow(im)

        # Retrieve and render each record.
        for layer_name in layer_names:
            for token in records_in_patch[layer_name]:
                record = self.map_api.get(layer_name, token)
                if layer_name == 'drivable_area':
                    polygon_tokens = record['polygon_tokens']
                else:
                    polygon_tokens = [record['polygon_token']]

                for polygon_token in polygon_tokens:
                    polygon = self.map_api.extract_polygon(polygon_token)

                    # Convert polygon nodes to pointcloud with 0 height.
                    points = np.array(polygon.exterior.xy)
                    points = np.vstack((points, np.zeros((1, points.shape[1]))))

                    # Transform into the ego vehicle frame for the timestamp of the image.
                    points = points - np.array(poserecord['translation']).reshape((-1, 1))
                    points = np.dot(Quaternion(poserecord['rotation']).rotation_matrix.T, points)

                    # Transform into the camera.
                    points = points - np.array(cs_record['translation']).reshape((-1, 1))
                    points = np.dot(Quaternion(cs_record['rotation']).rotation_matrix.T, points)

                    # Remove points that are partially behind the camera.
                    depths = points[2, :]
                    behind = depths < near_plane
                    if np.all(behind):
                        continue

                    if render_behind_cam:
                        # Perform clipping on polygons that are partially behind the camera.
                        points = self._clip_points_behind_camera(points, near_plane)
                    elif np.any(behind):
                        # Otherwise ignore any polygon that is partially behind the camera.
                        continue

                    # Ignore polygons with less than 3 points after clipping.
                    if len(points) == 0 or points.shape[1] < 3:
                        continue

                    # Take the actual picture (matrix multiplication with camera-matrix + renormalization).
                    points = view_points(points, cam_intrinsic, normalize=True)

                    # Skip polygons where all points are outside the image.
                    # Leave a margin of 1 pixel for aesthetic reasons.
                    inside = np.ones(points.shape[1], dtype=bool)
                    inside = np.logical_and(inside, points[0, :] > 1)
                    inside = np.logical_and(inside, points[0, :] < im.size[0] - 1)
                    inside = np.logical_and(inside, points[1, :] > 1)
                    inside = np.logical_and(inside, points[1, :] < im.size[1] - 1)
                    if render_outside_im:
                        if np.all(np.logical_not(inside)):
                            continue
                    else:
                        if np.any(np.logical_not(inside)):
                            continue

                    points = points[:2, :]
                    points = [(p0, p1) for (p0, p1) in zip(points[0], points[1])]
                    polygon_proj = Polygon(points)

                    # Filter small polygons
                    if polygon_proj.area < min_polygon_area:
                        continue

                    label = layer_name
                    ax.add_patch(polygon_patch(polygon_proj, fc=self.color_map[layer_name], alpha=alpha,
                                               label=label))

        # Display the image.
        plt.axis('off')
        ax.invert_yaxis()

        if out_path is not None:
            plt.tight_layout()
            plt.savefig(out_path, bbox_inches='tight', pad_inches=0)

        return fig, ax

    def render_egoposes_on_fancy_map(self, nusc, scene_tokens: List = None, verbose: bool = True,
                                     out_path: str = None, render_egoposes: bool = True,
                                     render_egoposes_range: bool = True, render_legend: bool = True, bitmap=None):
        """The LIDAR_TOP ego poses of every keyframe of the map's scenes (only `scene_tokens` when given) over
        `render_map_patch` of their extent; returns (the (n, 2) poses, fig, ax)."""
        from tqdm import tqdm

        plt = _pyplot()
        # Settings
        patch_margin = 2
        min_diff_patch = 30

        # Ids of scenes with a bad match between localization and map.
        scene_blacklist = [499, 515, 517]

        # Get logs by location.
        log_location = self.map_api.map_name
        log_tokens = [log['token'] for log in nusc.log if log['location'] == log_location]
        assert len(log_tokens) > 0, 'Error: This split has 0 scenes for location %s!' % log_location

        # Filter scenes.
        scene_tokens_location = [e['token'] for e in nusc.scene if e['log_token'] in log_tokens]
        if scene_tokens is not None:
            scene_tokens_location = [t for t in scene_tokens_location if t in scene_tokens]
        assert len(scene_tokens_location) > 0, 'Error: Found 0 valid scenes for location %s!' % log_location

        map_poses = []
        if verbose:
            print('Adding ego poses to map...')
        for scene_token in tqdm(scene_tokens_location, disable=not verbose):
            # Check that the scene is from the correct location.
            scene_record = nusc.get('scene', scene_token)
            scene_name = scene_record['name']
            scene_id = int(scene_name.replace('scene-', ''))
            log_record = nusc.get('log', scene_record['log_token'])
            assert log_record['location'] == log_location, \
                'Error: The provided scene_tokens do not correspond to the provided map location!'

            # Print a warning if the localization is known to be bad.
            if verbose and scene_id in scene_blacklist:
                print('Warning: %s is known to have a bad fit between ego pose and map.' % scene_name)

            # For each sample in the scene, store the ego pose.
            sample_tokens = nusc.field2token('sample', 'scene_token', scene_token)
            for sample_token in sample_tokens:
                sample_record = nusc.get('sample', sample_token)

                # Poses are associated with the sample_data. Here we use the lidar sample_data.
                sample_data_record = nusc.get('sample_data', sample_record['data']['LIDAR_TOP'])
                pose_record = nusc.get('ego_pose', sample_data_record['ego_pose_token'])

                # Calculate the pose on the map and append.
                map_poses.append(pose_record['translation'])

        # Check that ego poses aren't empty.
        assert len(map_poses) > 0, 'Error: Found 0 ego poses. Please check the inputs.'

        # Compute number of close ego poses.
        if verbose:
            print('Creating plot...')
        map_poses = np.vstack(map_poses)[:, :2]

        # Render the map patch with the current ego poses.
        min_patch = np.floor(map_poses.min(axis=0) - patch_margin)
        max_patch = np.ceil(map_poses.max(axis=0) + patch_margin)
        diff_patch = max_patch - min_patch
        if any(diff_patch < min_diff_patch):
            center_patch = (min_patch + max_patch) / 2
            diff_patch = np.maximum(diff_patch, min_diff_patch)
            min_patch = center_patch - diff_patch / 2
            max_patch = center_patch + diff_patch / 2
        my_patch = (min_patch[0], min_patch[1], max_patch[0], max_patch[1])
        fig, ax = self.render_map_patch(my_patch, self.map_api.non_geometric_layers, figsize=(10, 10),
                                        render_egoposes_range=render_egoposes_range,
                                        render_legend=render_legend, bitmap=bitmap)

        # Plot in the same axis as the map.
        # Make sure these are plotted "on top".
        if render_egoposes:
            ax.scatter(map_poses[:, 0], map_poses[:, 1], s=20, c='k', alpha=1.0, zorder=2)
        plt.axis('off')

        if out_path is not None:
            plt.savefig(out_path, bbox_inches='tight', pad_inches=0)

        return map_poses, fig, ax

    def render_next_roads(self, x: float, y: float, alpha: float = 0.5,
                          figsize: Union[None, float, Tuple[float, float]] = None, bitmap=None):
        """`get_next_roads(x, y)`'s records over the map, the point marked with a red x."""
        next_roads = self.map_api.get_next_roads(x, y)
        layer_names = []
        tokens = []
        for layer_name, layer_tokens in next_roads.items():
            if len(layer_tokens) > 0:
                layer_names.append(layer_name)
                tokens.extend(layer_tokens)

        # Render them.
        fig, ax = self.render_layers(layer_names, alpha, figsize, tokens=tokens, bitmap=bitmap)

        # Render current location with an x.
        ax.plot(x, y, 'x', markersize=12, color='red')

        return fig, ax

    @staticmethod
    def _clip_points_behind_camera(points, near_plane: float):
        """(3, n) camera-frame polygon points with each edge crossing the near plane cut at it
        (`rendering.pictures.map_in_image.clip_behind_camera`, the devkit's walk)."""
        from nuparquet.rendering.pictures.map_in_image import clip_behind_camera

        assert points.shape[0] == 3
        return clip_behind_camera(points, near_plane)

    def _render_layer(self, ax, layer_name: str, alpha: float, tokens: List[str] = None) -> None:
        if layer_name in self.map_api.non_geometric_polygon_layers:
            self._render_polygon_layer(ax, layer_name, alpha, tokens)
        elif layer_name in self.map_api.non_geometric_line_layers:
            self._render_line_layer(ax, layer_name, alpha, tokens)
        else:
            raise ValueError("{} is not a valid layer".format(layer_name))

    def _render_polygon_layer(self, ax, layer_name: str, alpha: float, tokens: List[str] = None) -> None:
        if layer_name not in self.map_api.non_geometric_polygon_layers:
            raise ValueError('{} is not a polygonal layer'.format(layer_name))

        first_time = True
        records = getattr(self.map_api, layer_name)
        if tokens is not None:
            records = [r for r in records if r['token'] in tokens]
        if layer_name == 'drivable_area':
            for record in records:
                polygons = [self.map_api.extract_polygon(polygon_token) for polygon_token in record['polygon_tokens']]

                for polygon in polygons:
                    if first_time:
                        label = layer_name
                        first_time = False
                    else:
                        label = None
                    ax.add_patch(polygon_patch(polygon, fc=self.color_map[layer_name], alpha=alpha, label=label))
        else:
            for record in records:
                polygon = self.map_api.extract_polygon(record['polygon_token'])

                if first_time:
                    label = layer_name
                    first_time = False
                else:
                    label = None

                ax.add_patch(polygon_patch(polygon, fc=self.color_map[layer_name], alpha=alpha, label=label))

    def _render_line_layer(self, ax, layer_name: str, alpha: float, tokens: List[str] = None) -> None:
        from matplotlib.patches import Arrow

        if layer_name not in self.map_api.non_geometric_line_layers:
            raise ValueError("{} is not a line layer".format(layer_name))

        first_time = True
        records = getattr(self.map_api, layer_name)
        if tokens is not None:
            records = [r for r in records if r['token'] in tokens]
        for record in records:
            if first_time:
                label = layer_name
                first_time = False
            else:
                label = None
            line = self.map_api.extract_line(record['line_token'])
            if line.is_empty:  # Skip lines without nodes
                continue
            xs, ys = line.xy

            if layer_name == 'traffic_light':
                # Draws an arrow with the physical traffic light as the starting point, pointing to the direction on
                # where the traffic light points.
                ax.add_patch(Arrow(xs[0], ys[0], xs[1] - xs[0], ys[1] - ys[0], color=self.color_map[layer_name],
                                   label=label))
            else:
                ax.plot(xs, ys, color=self.color_map[layer_name], alpha=alpha, label=label)

