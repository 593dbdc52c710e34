"""Map layers projected into a camera image: devkit `NuScenesMap.render_map_in_image`, step for step.

The records of `layer_names` within `patch_radius` of the ego (`records_in_patch`, intersect) give their polygons'
exteriors at height 0; each moves global -> ego at the image's time -> camera, is dropped when every point is behind
the near plane (1e-8 m), clipped there when partly behind (`render_behind_cam`, the devkit's edge walk: each edge
crossing the plane ends on it) or dropped (otherwise), dropped with fewer than 3 points, projected, dropped when no
point (or, without `render_outside_im`, not every point) lies 1 px inside the image, and dropped below
`min_polygon_area` square pixels; the rest are filled at `alpha` in the layer's colour, in layer then record order.
Returns (H, W, 3) uint8 RGB.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import shapely

from nuparquet import geometry
from nuparquet.dataset import as_dataset
from nuparquet.errors import UsageError
from nuparquet.frames.poses import sensor_poses
from nuparquet.frames.sweeps import keyframe_rows
from nuparquet.map.layers import POLYGON_LAYERS
from nuparquet.rendering import legend
from nuparquet.rendering.pictures.clouds import frame_frame
from nuparquet.rendering.decode import frame_image
from nuparquet.rendering.map_canvas import clip_ring, fill_polygons, layer_geometries
from nuparquet.rendering.palette import MAP_LAYER_RGB

NEAR_PLANE_M = 1e-8  # render_map_in_image's near plane
DEFAULT_LAYERS = ("road_segment", "lane", "ped_crossing", "walkway", "stop_line", "carpark_area")


def clip_behind_camera(points: np.ndarray, near_plane: float = NEAR_PLANE_M) -> np.ndarray:
    """(3, N) camera-frame polygon points -> (3, K) with each edge that crosses the near plane ending on it and
    points behind it dropped, as the devkit's `_clip_points_behind_camera` walks the edges (its duplicate test
    included)."""
    clipped: list[np.ndarray] = []
    count = points.shape[1]
    for i in range(count):
        p1, p2 = points[:, i], points[:, (i + 1) % count]
        z1, z2 = p1[2], p2[2]
        if z1 >= near_plane and z2 >= near_plane:
            if not clipped or all(clipped[-1] != p1):
                clipped.append(p1)
            clipped.append(p2)
        elif z1 < near_plane and z2 < near_plane:
            continue
        else:
            a, b = (p1, p2) if z1 <= z2 else (p2, p1)  # a behind, b in front
            alpha = (near_plane - b[2]) / (a[2] - b[2])
            crossing = a + (1 - alpha) * (b - a)
            if z1 >= near_plane and (not clipped or all(clipped[-1] != p1)):
                clipped.append(p1)
            clipped.append(crossing)
            if z2 >= near_plane:
                clipped.append(p2)
    return np.array(clipped).T if clipped else np.zeros((3, 0))


def projected_polygons(exteriors: Sequence[np.ndarray], camera_from_global: np.ndarray, intrinsic: np.ndarray,
                       size_px: tuple[int, int], *, min_polygon_area: float = 1000, render_behind_cam: bool = True,
                       render_outside_im: bool = True) -> list[np.ndarray | None]:
    """For each (N, 2) global exterior, its (K, 2) pixels as the devkit fills them, or None where it is dropped."""
    width, height = size_px
    out: list[np.ndarray | None] = []
    for exterior in exteriors:
        points = np.c_[exterior, np.zeros(len(exterior))]
        camera = geometry.transform_points(camera_from_global, points).T  # (3, N)
        behind = camera[2] < NEAR_PLANE_M
        if behind.all() or (not render_behind_cam and behind.any()):
            out.append(None)
            continue
        if render_behind_cam:
            camera = clip_behind_camera(camera)
        if camera.shape[1] < 3:
            out.append(None)
            continue
        uv = geometry.view_points(camera.T, intrinsic, normalize=True)[:, :2]
        inside = (uv[:, 0] > 1) & (uv[:, 0] < width - 1) & (uv[:, 1] > 1) & (uv[:, 1] < height - 1)
        if (render_outside_im and not inside.any()) or (not render_outside_im and not inside.all()):
            out.append(None)
            continue
        out.append(uv if shapely.Polygon(uv).area >= min_polygon_area else None)
    return out


def render_map_in_image(dataset_or_path, sample_token: str, camera_channel: str = "CAM_FRONT", alpha: float = 0.3,
                        patch_radius: float = 10000, min_polygon_area: float = 1000, render_behind_cam: bool = True,
                        render_outside_im: bool = True, layer_names: Sequence[str] | None = None, *,
                        scale: float = 1.0) -> np.ndarray:
    """The sample's `camera_channel` keyframe with the map's `layer_names` over it (the module docstring); `scale`
    resizes the picture (the polygons are selected on the full-size image, as the devkit does)."""
    dataset = as_dataset(dataset_or_path)
    layer_names = list(layer_names or DEFAULT_LAYERS)
    bad = [layer for layer in layer_names if layer not in POLYGON_LAYERS]
    if bad:
        raise UsageError(f"render_map_in_image draws polygon layers only ({', '.join(POLYGON_LAYERS)}), not "
                         f"{', '.join(bad)}")
    rows = frame_frame(dataset, keyframe_rows(dataset, sample_token, [camera_channel])["token"][0])
    camera = rows.row(0, named=True)
    if camera["modality"] != "camera":
        raise UsageError(f"{camera_channel} is not a camera")
    map_layers = dataset.map(camera["log_location"])
    global_from_ego, ego_from_camera = sensor_poses(rows)
    camera_from_global = geometry.invert_rigid(ego_from_camera[0]) @ geometry.invert_rigid(global_from_ego[0])
    intrinsic = np.reshape(camera["camera_intrinsic"], (3, 3))
    full = (int(camera["width"]), int(camera["height"]))
    size = (max(2, round(full[0] * scale)), max(2, round(full[1] * scale)))
    image = frame_image(dataset.sensors, camera, size, scale)
    ego_x, ego_y = global_from_ego[0][:2, 3]
    patch = shapely.box(ego_x - patch_radius, ego_y - patch_radius, ego_x + patch_radius, ego_y + patch_radius)
    resize = geometry.scale_pixels  # full-size pixels -> the picture's
    for layer in layer_names:
        tokens = map_layers.records_in_patch(patch.bounds, [layer], mode="intersect")[layer]
        geoms = layer_geometries(map_layers, layer, tokens=tokens)  # drivable_area: every polygon of each record
        # the exterior as the devkit's `polygon.exterior.xy` gives it: closed (the first point repeated at the end)
        exteriors = [np.asarray(g.exterior.coords).reshape(-1, 2) for g in geoms if g is not None and not g.is_empty]
        polygons = projected_polygons(exteriors, camera_from_global, intrinsic, full, min_polygon_area=min_polygon_area,
                                      render_behind_cam=render_behind_cam, render_outside_im=render_outside_im)
        # the part over the picture (and a margin): the far corners of a polygon clipped at the near plane lie too
        # far out for OpenCV's fixed-point pixels
        rings = [clip_ring(resize(p, np.asarray(size) / np.asarray(full)), -size[0], -size[1], 2 * size[0],
                           2 * size[1]) for p in polygons if p is not None]
        kept = [shapely.Polygon(ring) for ring in rings if len(ring) >= 3]
        if not kept:
            continue
        mask = np.zeros(image.shape[:2], np.uint8)
        fill_polygons(mask, kept, lambda xy: np.asarray(xy, np.float64), 1, 1)  # exteriors only, as the devkit
        where = mask.astype(bool)
        colour = np.asarray(MAP_LAYER_RGB[layer][::-1], np.float64)
        image[where] = np.rint(image[where] * (1 - alpha) + colour * alpha).astype(np.uint8)
    legend.draw_legend(image, [(layer, MAP_LAYER_RGB[layer]) for layer in layer_names], corner="top-right")
    return np.ascontiguousarray(image[..., ::-1])
