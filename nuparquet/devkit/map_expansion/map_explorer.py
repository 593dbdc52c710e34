"""`NuScenesMapExplorer`: the devkit's explorer of a `NuScenesMap`, its geometry methods over the converted map.

The queries go to `nuparquet.map.queries.MapLayers` (`map_api._map_layers`): `get_records_in_patch`,
`layers_on_point`, `record_on_point`, `get_bounds`, and `get_map_mask` (`map.mask`, pixel for pixel). The methods
clients override or call one by one are the devkit's Python, over the stored geometry: `extract_polygon` /
`extract_line` (the stored shapely geometry of the record, which is the devkit's `Polygon(exterior, holes)` of the
same nodes), `_get_layer_polygon` / `_get_layer_line` (the devkit's clip, rotation and shift per record, on the
records the layer's tree finds intersecting the patch: the others clip to nothing), `_polygon_geom_to_mask`,
`_line_geom_to_mask`, `mask_for_polygons`, `mask_for_lines` (each part of a MultiLineString drawn: the devkit's
loop over it raises TypeError under shapely 2), `get_map_geom`, `map_geom_to_mask`, `get_patch_coord`.

A subclass that overrides any step of `get_map_mask` (MapTR's `CNuScenesMapExplorer` overrides `_get_layer_line`
and `_get_layer_polygon`) gets the devkit's `get_map_mask`, built of its steps; `get_records_in_patch` likewise when
`is_record_in_patch` is overridden. The renderers are `map_renders`.

Longer than our ~300-line norm on purpose: clients subclass the explorer and override its steps by name, so each
step stays a method of the devkit's shape.
"""

from __future__ import annotations

from typing import Dict, List, Optional, Tuple, Union

import cv2
import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import LineString, MultiPolygon, Polygon, box

from nuparquet.devkit.map_expansion.map_renders import MapRenders

# Define a map geometry type for polygons and lines.
Geometry = Union[Polygon, LineString]

# the steps of the devkit's get_map_mask: overriding one of them opts out of the vectorised mask
MASK_STEPS = ("get_map_geom", "map_geom_to_mask", "_get_layer_geom", "_layer_geom_to_mask", "_get_layer_polygon",
              "_get_layer_line", "_polygon_geom_to_mask", "_line_geom_to_mask", "mask_for_polygons", "mask_for_lines",
              "get_patch_coord", "extract_polygon", "extract_line")
MAP_DIMS = {'singapore-onenorth': [1585.6, 2025.0], 'singapore-hollandvillage': [2808.3, 2922.9],
            'singapore-queenstown': [3228.6, 3687.1], 'boston-seaport': [2979.5, 2118.1]}


class NuScenesMapExplorer(MapRenders):
    """ Helper class to explore the nuScenes map data. """

    def __init__(self, map_api, representative_layers: Tuple[str] = ('drivable_area', 'lane', 'walkway'),
                 color_map: dict = None):
        # Mutable default argument.
        if color_map is None:
            color_map = dict(drivable_area='#a6cee3',
                             road_segment='#1f78b4',
                             road_block='#b2df8a',
                             lane='#33a02c',
                             ped_crossing='#fb9a99',
                             walkway='#e31a1c',
                             stop_line='#fdbf6f',
                             carpark_area='#ff7f00',
                             road_divider='#cab2d6',
                             lane_divider='#6a3d9a',
                             traffic_light='#7e772e')

        self.map_api = map_api
        self.representative_layers = representative_layers
        self.color_map = color_map

        self.canvas_max_x = self.map_api.canvas_edge[0]
        self.canvas_min_x = 0
        self.canvas_max_y = self.map_api.canvas_edge[1]
        self.canvas_min_y = 0
        self.canvas_aspect_ratio = (self.canvas_max_x - self.canvas_min_x) / (self.canvas_max_y - self.canvas_min_y)

    def _overrides(self, names) -> bool:
        """Whether this object's class replaces any of the explorer's methods `names`."""
        return any(getattr(type(self), name) is not getattr(NuScenesMapExplorer, name) for name in names)

    # --- masks and geometry in a patch ----------------------------------------------------------------------

    def get_map_geom(self, patch_box: Tuple[float, float, float, float], patch_angle: float,
                     layer_names: List[str]) -> List[Tuple[str, List[Geometry]]]:
        """[(layer, its geometries clipped to the patch, rotated by -patch_angle about its centre, centred on 0)]."""
        if layer_names is None:
            layer_names = self.map_api.non_geometric_layers

        map_geom = []
        for layer_name in layer_names:
            layer_geom = self._get_layer_geom(patch_box, patch_angle, layer_name)
            if layer_geom is None:
                continue
            map_geom.append((layer_name, layer_geom))

        return map_geom

    def map_geom_to_mask(self, map_geom: List[Tuple[str, List[Geometry]]], local_box: Tuple[float, float, float, float],
                         canvas_size: Tuple[int, int]) -> np.ndarray:
        map_mask = []
        for layer_name, layer_geom in map_geom:
            layer_mask = self._layer_geom_to_mask(layer_name, layer_geom, local_box, canvas_size)
            if layer_mask is not None:
                map_mask.append(layer_mask)

        return np.array(map_mask)

    def get_map_mask(self, patch_box: Optional[Tuple[float, float, float, float]], patch_angle: float,
                     layer_names: List[str] = None, canvas_size: Tuple[int, int] = (100, 100)) -> np.ndarray:
        """(C, H, W) uint8 masks of the patch [x_center, y_center, height, width] rotated by `patch_angle` degrees,
        one per layer but traffic_light (`map.mask`)."""
        if self.map_api.map_name not in MAP_DIMS:
            raise Exception('Error: Invalid map!')
        map_dims = MAP_DIMS[self.map_api.map_name]

        # If None, return the entire map.
        if patch_box is None:
            patch_box = [map_dims[0] / 2, map_dims[1] / 2, map_dims[1], map_dims[0]]

        if layer_names is None:
            layer_names = self.map_api.non_geometric_layers

        # If None, return the specified patch in the original scale of 10px/m.
        if canvas_size is None:
            map_scale = 10
            canvas_size = np.array((patch_box[2], patch_box[3])) * map_scale
            canvas_size = tuple(np.round(canvas_size).astype(np.int32))

        if self._overrides(MASK_STEPS):
            map_geom = self.get_map_geom(patch_box, patch_angle, layer_names)
            local_box = (0.0, 0.0, patch_box[2], patch_box[3])
            map_mask = self.map_geom_to_mask(map_geom, local_box, canvas_size)
        else:
            for layer_name in layer_names:  # the devkit's error, before any work
                if layer_name not in self.map_api.non_geometric_layers:
                    raise ValueError("{} is not a valid layer".format(layer_name))
            map_mask = self.map_api._map_layers.map_mask(tuple(patch_box), patch_angle, list(layer_names),
                                                         tuple(canvas_size)) if len(layer_names) else np.array([])
        assert np.all(map_mask.shape[1:] == canvas_size)

        return map_mask

    def _get_layer_geom(self, patch_box: Tuple[float, float, float, float], patch_angle: float,
                        layer_name: str) -> List[Geometry]:
        if layer_name in self.map_api.non_geometric_polygon_layers:
            return self._get_layer_polygon(patch_box, patch_angle, layer_name)
        elif layer_name in self.map_api.non_geometric_line_layers:
            return self._get_layer_line(patch_box, patch_angle, layer_name)
        else:
            raise ValueError("{} is not a valid layer".format(layer_name))

    def _layer_geom_to_mask(self, layer_name: str, layer_geom: List[Geometry],
                            local_box: Tuple[float, float, float, float], canvas_size: Tuple[int, int]) -> np.ndarray:
        if layer_name in self.map_api.non_geometric_polygon_layers:
            return self._polygon_geom_to_mask(layer_geom, local_box, layer_name, canvas_size)
        elif layer_name in self.map_api.non_geometric_line_layers:
            return self._line_geom_to_mask(layer_geom, local_box, layer_name, canvas_size)
        else:
            raise ValueError("{} is not a valid layer".format(layer_name))

    @staticmethod
    def mask_for_polygons(polygons: MultiPolygon, mask: np.ndarray) -> np.ndarray:
        """Fill a (multi)polygon's exteriors with 1 and clear its holes on `mask` (OpenCV)."""
        if not polygons:
            return mask

        def int_coords(x):
            # function to round and convert to int
            return np.array(x).round().astype(np.int32)
        exteriors = [int_coords(poly.exterior.coords) for poly in polygons.geoms]
        interiors = [int_coords(pi.coords) for poly in polygons.geoms for pi in poly.interiors]
        cv2.fillPoly(mask, exteriors, 1)
        cv2.fillPoly(mask, interiors, 0)
        return mask

    @staticmethod
    def mask_for_lines(lines: LineString, mask: np.ndarray) -> np.ndarray:
        """Draw a line (each part of a MultiLineString) on `mask`, 2 px wide."""
        for line in shapely.get_parts(lines):  # the devkit's `for line in lines` raises under shapely 2
            coords = np.asarray(list(line.coords), np.int32)
            coords = coords.reshape((-1, 2))
            cv2.polylines(mask, [coords], False, 1, 2)

        return mask

    def _polygon_geom_to_mask(self, layer_geom: List[Polygon], local_box: Tuple[float, float, float, float],
                              layer_name: str, canvas_size: Tuple[int, int]) -> np.ndarray:
        if layer_name not in self.map_api.non_geometric_polygon_layers:
            raise ValueError('{} is not a polygonal layer'.format(layer_name))

        patch_x, patch_y, patch_h, patch_w = local_box
        patch = self.get_patch_coord(local_box)
        canvas_h = canvas_size[0]
        canvas_w = canvas_size[1]
        scale_height = canvas_h / patch_h
        scale_width = canvas_w / patch_w
        trans_x = -patch_x + patch_w / 2.0
        trans_y = -patch_y + patch_h / 2.0

        map_mask = np.zeros(canvas_size, np.uint8)

        for polygon in layer_geom:
            new_polygon = polygon.intersection(patch)
            if not new_polygon.is_empty:
                new_polygon = affinity.affine_transform(new_polygon, [1.0, 0.0, 0.0, 1.0, trans_x, trans_y])
                new_polygon = affinity.scale(new_polygon, xfact=scale_width, yfact=scale_height, origin=(0, 0))

                if new_polygon.geom_type == 'Polygon':
                    new_polygon = MultiPolygon([new_polygon])
                map_mask = self.mask_for_polygons(new_polygon, map_mask)

        return map_mask

    def _line_geom_to_mask(self, layer_geom: List[LineString], local_box: Tuple[float, float, float, float],
                           layer_name: str, canvas_size: Tuple[int, int]) -> Optional[np.ndarray]:
        if layer_name not in self.map_api.non_geometric_line_layers:
            raise ValueError("{} is not a line layer".format(layer_name))

        patch_x, patch_y, patch_h, patch_w = local_box
        patch = self.get_patch_coord(local_box)
        canvas_h = canvas_size[0]
        canvas_w = canvas_size[1]
        scale_height = canvas_h / patch_h
        scale_width = canvas_w / patch_w
        trans_x = -patch_x + patch_w / 2.0
        trans_y = -patch_y + patch_h / 2.0

        map_mask = np.zeros(canvas_size, np.uint8)

        if layer_name == 'traffic_light':
            return None

        for line in layer_geom:
            new_line = line.intersection(patch)
            if not new_line.is_empty:
                new_line = affinity.affine_transform(new_line, [1.0, 0.0, 0.0, 1.0, trans_x, trans_y])
                new_line = affinity.scale(new_line, xfact=scale_width, yfact=scale_height, origin=(0, 0))

                map_mask = self.mask_for_lines(new_line, map_mask)
        return map_mask

    def _candidates(self, tree, patch) -> np.ndarray:
        """The rows (in order) of the geometries whose boxes meet the patch and that intersect it."""
        return np.sort(tree.query(patch, predicate="intersects"))

    def _get_layer_polygon(self, patch_box: Tuple[float, float, float, float], patch_angle: float,
                           layer_name: str) -> List[Polygon]:
        """The layer's polygons clipped to the patch, rotated by -patch_angle about its centre and moved so the
        centre is 0 (each a MultiPolygon where the clip is one Polygon), in record (and drivable_area: polygon)
        order."""
        if layer_name not in self.map_api.non_geometric_polygon_layers:
            raise ValueError('{} is not a polygonal layer'.format(layer_name))

        patch_x = patch_box[0]
        patch_y = patch_box[1]

        patch = self.get_patch_coord(patch_box, patch_angle)
        parts = self.map_api._map_layers.parts[layer_name]

        polygon_list = []
        for i in self._candidates(parts.tree, patch):
            polygon = parts.geometry[i]
            if layer_name == 'drivable_area' or polygon.is_valid:  # the devkit skips invalid ones but drivable area's
                new_polygon = polygon.intersection(patch)
                if not new_polygon.is_empty:
                    new_polygon = affinity.rotate(new_polygon, -patch_angle,
                                                  origin=(patch_x, patch_y), use_radians=False)
                    new_polygon = affinity.affine_transform(new_polygon,
                                                            [1.0, 0.0, 0.0, 1.0, -patch_x, -patch_y])
                    if new_polygon.geom_type == 'Polygon':
                        new_polygon = MultiPolygon([new_polygon])
                    polygon_list.append(new_polygon)

        return polygon_list

    def _get_layer_line(self, patch_box: Tuple[float, float, float, float], patch_angle: float,
                        layer_name: str) -> Optional[List[LineString]]:
        """The layer's lines clipped to the patch, rotated and moved as `_get_layer_polygon`'s; None for
        traffic_light."""
        if layer_name not in self.map_api.non_geometric_line_layers:
            raise ValueError("{} is not a line layer".format(layer_name))

        if layer_name == 'traffic_light':
            return None

        patch_x = patch_box[0]
        patch_y = patch_box[1]

        patch = self.get_patch_coord(patch_box, patch_angle)
        records = self.map_api._map_layers.layers[layer_name]

        line_list = []
        for i in self._candidates(records.tree, patch):
            new_line = records.geometry[i].intersection(patch)
            if not new_line.is_empty:
                new_line = affinity.rotate(new_line, -patch_angle, origin=(patch_x, patch_y), use_radians=False)
                new_line = affinity.affine_transform(new_line, [1.0, 0.0, 0.0, 1.0, -patch_x, -patch_y])
                line_list.append(new_line)

        return line_list

    @staticmethod
    def get_patch_coord(patch_box: Tuple[float, float, float, float], patch_angle: float = 0.0) -> Polygon:
        """The patch [x_center, y_center, height, width] as a box rotated by `patch_angle` degrees."""
        patch_x, patch_y, patch_h, patch_w = patch_box

        x_min = patch_x - patch_w / 2.0
        y_min = patch_y - patch_h / 2.0
        x_max = patch_x + patch_w / 2.0
        y_max = patch_y + patch_h / 2.0

        patch = box(x_min, y_min, x_max, y_max)
        patch = affinity.rotate(patch, patch_angle, origin=(patch_x, patch_y), use_radians=False)

        return patch

    # --- records by place -----------------------------------------------------------------------------------

    def get_records_in_patch(self, box_coords: Tuple[float, float, float, float], layer_names: List[str] = None,
                             mode: str = 'intersect') -> Dict[str, List[str]]:
        """{layer: tokens of its records intersecting / within the box (x_min, y_min, x_max, y_max)}, file order
        (`MapLayers.records_in_patch`: line records by their nodes strictly inside, as the devkit)."""
        if mode not in ['intersect', 'within']:
            raise ValueError("Mode {} is not valid, choice=('intersect', 'within')".format(mode))

        if layer_names is None:
            layer_names = self.map_api.non_geometric_layers

        if self._overrides(("is_record_in_patch",)):
            return {layer_name: [record['token'] for record in getattr(self.map_api, layer_name)
                                 if self.is_record_in_patch(layer_name, record['token'], box_coords, mode)]
                    for layer_name in layer_names}
        if not len(layer_names):
            return {}
        for layer_name in layer_names:  # the devkit's getattr(map_api, layer_name) of a name that is no layer
            if layer_name not in self.map_api.layer_names:
                raise AttributeError(f"'NuScenesMap' object has no attribute '{layer_name}'")
        return self.map_api._map_layers.records_in_patch(tuple(box_coords), list(layer_names), mode)

    def is_record_in_patch(self, layer_name: str, token: str, box_coords: Tuple[float, float, float, float],
                           mode: str = 'intersect') -> bool:
        if mode not in ['intersect', 'within']:
            raise ValueError("Mode {} is not valid, choice=('intersect', 'within')".format(mode))

        if layer_name in self.map_api.lookup_polygon_layers:
            return self._is_polygon_record_in_patch(token, layer_name, box_coords, mode)
        elif layer_name in self.map_api.non_geometric_line_layers:
            return self._is_line_record_in_patch(token, layer_name, box_coords, mode)
        else:
            raise ValueError("{} is not a valid layer".format(layer_name))

    def _is_polygon_record_in_patch(self, token: str, layer_name: str, box_coords: Tuple[float, float, float, float],
                                    mode: str = 'intersect') -> bool:
        if layer_name not in self.map_api.lookup_polygon_layers:
            raise ValueError('{} is not a polygonal layer'.format(layer_name))

        x_min, y_min, x_max, y_max = box_coords
        record = self.map_api.get(layer_name, token)
        rectangular_patch = box(x_min, y_min, x_max, y_max)

        if layer_name == 'drivable_area':
            polygons = [self.map_api.extract_polygon(polygon_token) for polygon_token in record['polygon_tokens']]
            geom = MultiPolygon(polygons)
        else:
            geom = self.map_api.extract_polygon(record['polygon_token'])

        if mode == 'intersect':
            return geom.intersects(rectangular_patch)
        elif mode == 'within':
            return geom.within(rectangular_patch)

    def _is_line_record_in_patch(self, token: str, layer_name: str, box_coords: Tuple[float, float, float, float],
                                 mode: str = 'intersect') -> bool:
        if layer_name not in self.map_api.non_geometric_line_layers:
            raise ValueError("{} is not a line layer".format(layer_name))

        record = self.map_api.get(layer_name, token)
        node_recs = [self.map_api.get('node', node_token) for node_token in record['node_tokens']]
        node_coords = np.array([[node['x'], node['y']] for node in node_recs])

        # A few lines in Queenstown have zero nodes. In this case we return False.
        if len(node_coords) == 0:
            return False

        # Check that nodes fall inside the path.
        x_min, y_min, x_max, y_max = box_coords
        cond_x = np.logical_and(node_coords[:, 0] < x_max, node_coords[:, 0] > x_min)
        cond_y = np.logical_and(node_coords[:, 1] < y_max, node_coords[:, 1] > y_min)
        cond = np.logical_and(cond_x, cond_y)
        if mode == 'intersect':
            return np.any(cond)
        elif mode == 'within':
            return np.all(cond)

    def layers_on_point(self, x: float, y: float, layer_names: List[str] = None) -> Dict[str, str]:
        """{polygon layer: the first record strictly holding (x, y), '' where none} (`MapLayers.layers_on_point`)."""
        if layer_names is None:
            layer_names = self.map_api.non_geometric_polygon_layers
        for layer_name in layer_names:
            if layer_name not in self.map_api.non_geometric_polygon_layers:
                raise ValueError("{} is not a polygon layer".format(layer_name))
        if not len(layer_names):
            return {}
        found = self.map_api._map_layers.layers_on_point(x, y, list(layer_names))
        return {layer_name: str(found[layer_name][0]) for layer_name in layer_names}

    def record_on_point(self, x: float, y: float, layer_name: str) -> str:
        """The first record of polygon layer `layer_name` strictly holding (x, y), '' where none."""
        if layer_name not in self.map_api.non_geometric_polygon_layers:
            raise ValueError("{} is not a polygon layer".format(layer_name))
        return self.map_api._map_layers.record_on_point(x, y, layer_name)

    # --- records' shapes ------------------------------------------------------------------------------------

    def _stored(self, layer_name: str, token: str):
        """The stored geometry of a `polygon` or `line` record (KeyError for an unknown token, as the devkit's)."""
        return self.map_api._map_layers.layers[layer_name].geometry[self.map_api.getind(layer_name, token)]

    def extract_polygon(self, polygon_token: str) -> Polygon:
        """The shapely Polygon of a polygon record (its exterior and non-empty holes)."""
        stored = self._stored('polygon', polygon_token)
        if stored is not None:
            return stored
        # a ring of fewer than 3 nodes is stored without geometry: the devkit's construction (and its error)
        polygon_record = self.map_api.get('polygon', polygon_token)
        exterior_coords = [(self.map_api.get('node', token)['x'], self.map_api.get('node', token)['y'])
                           for token in polygon_record['exterior_node_tokens']]
        interiors = []
        for hole in polygon_record['holes']:
            interior_coords = [(self.map_api.get('node', token)['x'], self.map_api.get('node', token)['y'])
                               for token in hole['node_tokens']]
            if len(interior_coords) > 0:  # Add only non-empty holes.
                interiors.append(interior_coords)
        return Polygon(exterior_coords, interiors)

    def extract_line(self, line_token: str) -> LineString:
        """The shapely LineString of a line record (empty for a line without nodes)."""
        stored = self._stored('line', line_token)
        if stored is not None:
            return stored
        line_record = self.map_api.get('line', line_token)
        line_nodes = [(self.map_api.get('node', token)['x'], self.map_api.get('node', token)['y'])
                      for token in line_record['node_tokens']]
        return LineString(line_nodes)

    def get_bounds(self, layer_name: str, token: str) -> Tuple[float, float, float, float]:
        """(min_x, min_y, max_x, max_y) of the record's nodes (`MapLayers.bounds`), numpy floats as the devkit's."""
        if layer_name not in self.map_api.non_geometric_layers:
            raise ValueError("{} is not a valid layer".format(layer_name))
        self.map_api.getind(layer_name, token)  # the devkit's KeyError for an unknown token
        return tuple(np.float64(v) for v in self.map_api._map_layers.bounds(layer_name, token))

    def _get_polygon_bounds(self, layer_name: str, token: str) -> Tuple[float, float, float, float]:
        if layer_name not in self.map_api.non_geometric_polygon_layers:
            raise ValueError("{} is not a record with polygon representation".format(token))
        return self.get_bounds(layer_name, token)

    def _get_line_bounds(self, layer_name: str, token: str) -> Tuple[float, float, float, float]:
        if layer_name not in self.map_api.non_geometric_line_layers:
            raise ValueError("{} is not a record with line representation".format(token))
        return self.get_bounds(layer_name, token)

    def _get_figsize(self, figsize: Union[None, float, Tuple[float, float]]) -> Tuple[float, float]:
        """The figure size: None the canvas / 200, a scalar that times it, a 2-tuple itself."""
        canvas_size = np.array(self.map_api.canvas_edge)[::-1] / 200

        if figsize is None:
            return tuple(canvas_size)
        elif type(figsize) in [int, float]:
            return tuple(canvas_size * figsize)
        elif type(figsize) == tuple and len(figsize) == 2:
            return figsize
        else:
            raise Exception('Error: Invalid figsize: %s' % figsize)
