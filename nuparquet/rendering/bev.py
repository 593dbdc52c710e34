"""The bird's-eye view (a `render.plan.TileSource`): map layers, reference-lidar points coloured by height (or
by class, instance or intensity with `--lidar-color`),
boxes as oriented rectangles with a heading line in their category colours, the ego vehicle and a legend,
centred on the ego vehicle, north-up or ego-up.

The map is rasterised once per scene (`MapRaster`: every layer's polygons over the scene's extent, at the
output's pixels per metre, `map_canvas`'s polygon and line drawing); each output warps it into the view with one
`cv2.warpAffine`. Points and boxes go through one view transform per output over all their coordinates at once;
points are set by array indexing, boxes drawn by one `cv2.polylines` call per colour.

Pixel convention: pixel (u, v) has its centre at (u, v); u grows east (north-up) or to the ego's right
(ego-up), v grows south / backwards.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import shapely

from nuparquet.frames.boxes import FrameBoxes, FramedCuboids
from nuparquet.rendering.map_canvas import draw_lines, fill_polygons, layer_geometries
from nuparquet.rendering.palette import category_rgb
from nuparquet.geometry.quaternions import heading_from_quaternions
from nuparquet.rendering.plan import RowTile, TileLoad
from nuparquet.rendering.points import CloudReader

BACKGROUND_BGR = (32, 32, 32)
# Draw order, bottom to top: (layer, BGR, how). Lines are drawn with the given thickness (pixels).
MAP_STYLE: tuple[tuple[str, tuple[int, int, int], str], ...] = (
    ("drivable_area", (78, 78, 78), "fill"),
    ("carpark_area", (60, 90, 120), "fill"),
    ("walkway", (70, 115, 70), "fill"),
    ("lane", (98, 98, 98), "fill"),
    ("ped_crossing", (165, 165, 165), "fill"),
    ("stop_line", (50, 50, 200), "fill"),
    ("road_divider", (0, 200, 235), "line"),
    ("lane_divider", (215, 215, 215), "line"),
)
EGO_SIZE_LW_M = (4.084, 1.73)  # nuScenes' Renault Zoe, length x width
EGO_BGR = (255, 255, 255)
POINT_HEIGHT_RANGE_M = (-2.0, 4.0)  # ego-frame z mapped onto the colour map
_HEIGHT_LUT = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_TURBO)[:, 0, :]


@dataclass(frozen=True)
class View:
    """The output tile: size (width, height) px, `range_m` from the centre to the top edge, north- or ego-up."""

    size: tuple[int, int]
    range_m: float
    ego_up: bool

    @property
    def px_per_m(self) -> float:
        return self.size[1] / (2.0 * self.range_m)

    def world_to_pixel(self, ego_xy: np.ndarray, ego_yaw: float) -> np.ndarray:
        """(2, 3) affine: global (x, y) -> tile pixel (u, v)."""
        s = self.px_per_m
        theta = (np.pi / 2 - ego_yaw) if self.ego_up else 0.0  # rotates the ego's heading onto "up"
        c, n = np.cos(theta), np.sin(theta)
        cx, cy = (self.size[0] - 1) / 2.0, (self.size[1] - 1) / 2.0
        rotation = np.array([[s * c, -s * n], [-s * n, -s * c]])  # u = s * d_x, v = -s * d_y
        return np.c_[rotation, np.array([cx, cy]) - rotation @ ego_xy]


def _apply(affine: np.ndarray, xy: np.ndarray) -> np.ndarray:
    return xy @ affine[:, :2].T + affine[:, 2]


@dataclass(frozen=True)
class MapRaster:
    """The scene's map layers drawn once, north-up: pixel (U, V) centre at global (x0 + U / s, y1 - V / s)."""

    image: np.ndarray  # (H, W, 3) uint8
    x0_m: float
    y1_m: float
    px_per_m: float
    has_map: bool = False  # the map layers were drawn (False: the background only, no map converted)

    @classmethod
    def build(cls, map_layers, extent: tuple[float, float, float, float], px_per_m: float) -> MapRaster:
        """`map_layers`: a `nuparquet.map.queries.MapLayers` (or None: background only); extent (xmin, ymin,
        xmax, ymax) global metres to cover."""
        xmin, ymin, xmax, ymax = extent
        width = int(np.ceil((xmax - xmin) * px_per_m)) + 1
        height = int(np.ceil((ymax - ymin) * px_per_m)) + 1
        image = np.empty((height, width, 3), np.uint8)
        image[:] = BACKGROUND_BGR
        raster = cls(image, xmin, ymax, px_per_m, has_map=map_layers is not None)
        if map_layers is None:
            return raster
        box = shapely.box(xmin, ymin, xmax, ymax)
        for layer, color, how in MAP_STYLE:
            geoms = layer_geometries(map_layers, layer, box)
            if how == "fill":
                fill_polygons(raster.image, geoms, raster.to_pixels, color, BACKGROUND_BGR)
            else:
                draw_lines(raster.image, geoms, raster.to_pixels, color, thickness=2 if layer == "road_divider" else 1)
        return raster

    def to_pixels(self, xy: np.ndarray) -> np.ndarray:
        return np.c_[(xy[:, 0] - self.x0_m) * self.px_per_m, (self.y1_m - xy[:, 1]) * self.px_per_m]

    def warp(self, size: tuple[int, int], world_to_pixel: np.ndarray) -> np.ndarray:
        """The raster as seen by a picture of `size` (width, height): (H, W, 3) for the affine `world_to_pixel`
        (global -> picture pixel)."""
        raster_from_world = np.array([[self.px_per_m, 0.0, -self.x0_m * self.px_per_m],
                                      [0.0, -self.px_per_m, self.y1_m * self.px_per_m]])
        world_from_tile = cv2.invertAffineTransform(world_to_pixel)
        raster_from_tile = raster_from_world[:, :2] @ world_from_tile
        raster_from_tile[:, 2] += raster_from_world[:, 2]
        return cv2.warpAffine(self.image, raster_from_tile, tuple(size), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=BACKGROUND_BGR)


def footprints(translation_m: np.ndarray, size_wlh_m: np.ndarray, heading_rad: np.ndarray) -> np.ndarray:
    """(B, 5, 2) global footprint corners (front-left, front-right, rear-right, rear-left) then the front centre,
    of boxes whose x axis points at `heading_rad` (B,)."""
    heading = np.asarray(heading_rad, dtype=np.float64)
    half_l, half_w = size_wlh_m[:, 1] / 2, size_wlh_m[:, 0] / 2
    local = np.stack([np.c_[half_l, half_w], np.c_[half_l, -half_w], np.c_[-half_l, -half_w], np.c_[-half_l, half_w],
                      np.c_[half_l, np.zeros_like(half_l)]], axis=1)  # (B, 5, 2) box frame, x forward
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x = c * local[..., 0] - s * local[..., 1] + translation_m[:, None, 0]
    y = s * local[..., 0] + c * local[..., 1] + translation_m[:, None, 1]
    return np.stack([x, y], axis=-1)


@dataclass(frozen=True)
class BevTile(RowTile):
    """The bird's-eye view of each output: lidar frame `rows[t]` (-1: none) of the reference lidar's frames.

    global_from_ego, ego_from_sensor: (L, 4, 4) per lidar frame; clouds: their points (from lidar_points/ or the
    files, with labels for a label colouring; None: no points); boxes: the boxes of every lidar frame
    (`frame_boxes`, `frame_index` = lidar row).
    """

    rows: np.ndarray
    view: View
    raster: MapRaster
    global_from_ego: np.ndarray
    ego_from_sensor: np.ndarray
    clouds: CloudReader | None
    boxes: FrameBoxes
    label: str = "BEV"
    predictions: FramedCuboids | None = None  # predicted boxes per lidar row (`render.predictions`), thin outlines
    prediction_colors_rgb: np.ndarray | None = None  # (M, 3)
    tokens: tuple[str, ...] = ()  # (L,) sample_data token of each lidar frame (the frame index)
    timestamps_us: np.ndarray | None = None  # (L,)
    prediction_legend: tuple = ()  # (name, RGB) entries: what the predictions' colours mean

    def load(self, t: int) -> TileLoad:
        row = self.key(t)
        if row is None:
            return TileLoad()
        if self.clouds is None:
            return TileLoad((row, None))
        try:
            cloud = self.clouds.cloud(row)
        except (OSError, ValueError):
            return TileLoad((row, None), (self.clouds.paths[row],))
        return TileLoad((row, cloud))

    def draw(self, t: int, loaded: TileLoad) -> np.ndarray | None:
        if loaded.data is None:
            return None
        row, cloud = loaded.data
        ego = self.global_from_ego[row]
        ego_yaw = float(np.arctan2(ego[1, 0], ego[0, 0]))
        to_pixel = self.view.world_to_pixel(ego[:2, 3], ego_yaw)
        image = self.raster.warp(self.view.size, to_pixel)
        points_drawn = cloud is not None and len(cloud[0]) > 0
        if points_drawn:
            self._draw_points(image, *cloud, row, to_pixel)
        self._draw_boxes(image, row, to_pixel)
        if self.predictions is not None:
            self._draw_predictions(image, row, to_pixel)
        self._draw_ego(image, ego[:2, 3], ego_yaw, to_pixel)
        # the point colouring is explained only where points are drawn (no bar over a picture without any)
        points = None if not points_drawn else "height" if self.clouds.color == "depth" else self.clouds.color
        draw_legend(image, points=points, map_layers=self.raster.has_map)
        if self.predictions is not None:
            from nuparquet.rendering import legend

            legend.draw_legend(image, self.prediction_legend, corner="top-right", max_chars=40)
        return image

    def _draw_points(self, image: np.ndarray, points: np.ndarray, labels: np.ndarray | None, row: int,
                     to_pixel: np.ndarray) -> None:
        sensor_xyz = points[:, :3].astype(np.float64)
        ego_xyz = sensor_xyz @ self.ego_from_sensor[row][:3, :3].T + self.ego_from_sensor[row][:3, 3]
        global_xyz = ego_xyz @ self.global_from_ego[row][:3, :3].T + self.global_from_ego[row][:3, 3]
        uv = np.round(_apply(to_pixel, global_xyz[:, :2])).astype(np.int64)
        h, w = image.shape[:2]
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] < h - 1)
        color = self.clouds.colors_bgr(points, labels, np.flatnonzero(inside))  # lidarseg, panoptic, intensity
        if color is None:  # height (the depth of a top-down view)
            lo, hi = POINT_HEIGHT_RANGE_M
            color = _HEIGHT_LUT[np.clip((ego_xyz[inside, 2] - lo) / (hi - lo) * 255, 0, 255).astype(np.uint8)]
        u, v = uv[inside, 0], uv[inside, 1]
        for du, dv in ((0, 0), (1, 0), (0, 1), (1, 1)):  # 2 x 2 px dots
            image[v + dv, u + du] = color

    def _draw_boxes(self, image: np.ndarray, row: int, to_pixel: np.ndarray) -> None:
        lo, hi = np.searchsorted(self.boxes.frame_index, [row, row + 1])
        if hi == lo:
            return
        boxes = self.boxes.take(slice(lo, hi))
        corners = footprints(boxes.translation_m, boxes.size_wlh_m, heading_from_quaternions(boxes.rotation_wxyz))
        px = np.round(_apply(to_pixel, corners.reshape(-1, 2)) * 8).astype(np.int32).reshape(-1, 5, 2)
        centres = np.round(_apply(to_pixel, boxes.translation_m[:, :2]) * 8).astype(np.int32)
        names = boxes.category_name
        for name in np.unique(names):  # one call per colour over all its boxes
            mine = names == name
            r, g, b = category_rgb(str(name))
            outlines = list(px[mine, :4])
            headings = [np.stack([c, f]) for c, f in zip(centres[mine], px[mine, 4])]
            cv2.polylines(image, outlines + headings, True, (b, g, r), 2, lineType=cv2.LINE_AA, shift=3)

    def _draw_predictions(self, image: np.ndarray, row: int, to_pixel: np.ndarray) -> None:
        """The predicted boxes of lidar row `row`: 1 px outlines and heading lines in their status colours."""
        lo, hi = np.searchsorted(self.predictions.frame_index, [row, row + 1])
        if hi == lo:
            return
        boxes = self.predictions.take(slice(lo, hi))
        corners = footprints(boxes.translation_m, boxes.size_wlh_m, heading_from_quaternions(boxes.rotation_wxyz))
        px = np.round(_apply(to_pixel, corners.reshape(-1, 2)) * 8).astype(np.int32).reshape(-1, 5, 2)
        centres = np.round(_apply(to_pixel, boxes.translation_m[:, :2]) * 8).astype(np.int32)
        colors, group = np.unique(self.prediction_colors_rgb[lo:hi], axis=0, return_inverse=True)
        for i, (r, g, b) in enumerate(colors.tolist()):
            mine = group.reshape(-1) == i
            outlines = list(px[mine, :4])
            headings = [np.stack([c, f]) for c, f in zip(centres[mine], px[mine, 4])]
            cv2.polylines(image, outlines + headings, True, (b, g, r), 1, lineType=cv2.LINE_AA, shift=3)

    def _draw_ego(self, image: np.ndarray, ego_xy: np.ndarray, ego_yaw: float, to_pixel: np.ndarray) -> None:
        length, width = EGO_SIZE_LW_M
        corners = footprints(np.array([[ego_xy[0], ego_xy[1], 0.0]]), np.array([[width, length, 1.5]]),
                             np.array([ego_yaw]))[0]
        px = np.round(_apply(to_pixel, corners) * 8).astype(np.int32)
        cv2.fillPoly(image, [px[:4]], EGO_BGR, lineType=cv2.LINE_AA, shift=3)
        tip = np.round(_apply(to_pixel, corners[4:5])).astype(np.int32)[0]
        cv2.circle(image, (int(tip[0]), int(tip[1])), 2, (0, 0, 255), -1)


LEGEND = tuple((layer.replace("_", " "), color) for layer, color, _ in MAP_STYLE)


def draw_legend(image: np.ndarray, points: str | None = "height", map_layers: bool = True) -> None:
    """Layer swatches (only when the map was drawn: `map_layers`) and the point colouring (the height scale, or the
    name of the colouring; None: no points drawn, nothing said) in the top-left corner."""
    h = image.shape[0]
    font = max(0.3, h / 1800)
    step = max(10, int(22 * font * 2))
    x, y = 6, 6
    legend = LEGEND if map_layers else ()
    if not legend and points is None:
        return
    panel_h = step * (len(legend) + (2 if points is not None else 0)) + 6
    panel_w = int(150 * font * 2.2)
    image[y:y + panel_h, x:x + panel_w] = (image[y:y + panel_h, x:x + panel_w] * 0.35).astype(np.uint8)
    for i, (name, color) in enumerate(legend):
        top = y + 4 + i * step
        cv2.rectangle(image, (x + 4, top), (x + 4 + step - 4, top + step - 4), color, -1)
        cv2.putText(image, name, (x + step + 6, top + step - 5), cv2.FONT_HERSHEY_SIMPLEX, font, (255, 255, 255), 1,
                    cv2.LINE_AA)
    if points is None:
        return
    top = y + 4 + len(legend) * step
    lo, hi = POINT_HEIGHT_RANGE_M
    text = f"points: {points}"
    if points == "height":
        bar = _HEIGHT_LUT[np.linspace(0, 255, panel_w - 12).astype(np.uint8)]
        region = image[top + 2:top + step - 4, x + 4:x + 4 + len(bar)]  # cut where a small view ends
        region[:] = bar[None, :region.shape[1]]
        text += f" {lo:g}..{hi:g} m"
    cv2.putText(image, text, (x + 4, top + 2 * step - 5), cv2.FONT_HERSHEY_SIMPLEX, font, (255, 255, 255), 1,
                cv2.LINE_AA)


def scene_extent(ego_xy: np.ndarray, view: View) -> tuple[float, float, float, float]:
    """The global box every view of the scene can show: the ego path plus the tile's half-diagonal."""
    half_diag_m = np.hypot(*view.size) / 2 / view.px_per_m + 2.0
    lo, hi = ego_xy.min(axis=0) - half_diag_m, ego_xy.max(axis=0) + half_diag_m
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


