"""A picture of a plane seen from above, with the devkit's axes: x to the right, y up (`render_sample_data`'s lidar
and radar views: x forward, y left; `render_annotation`'s lidar view in the sensor frame). Drawing only: points,
box outlines seen from above, arrows (radar velocities), the ego marker and the map underneath, all given in the
plane's metres.

Pixel convention: pixel (u, v) has its centre at (u, v); u = (x - x_min) * s - 0.5, v = (y_max - y) * s - 0.5 for
`s` pixels per metre, so the picture covers exactly [x_min, x_max] x [y_min, y_max].
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from nuparquet.rendering import draw
from nuparquet.rendering.bev import BACKGROUND_BGR, MapRaster

EGO_MARKER_BGR = (0, 0, 255)  # the devkit's red 'x' at the ego


@dataclass(frozen=True)
class PlaneView:
    """The rectangle [x_min, x_max] x [y_min, y_max] metres of a plane, drawn at `px_per_m`."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    px_per_m: float

    @classmethod
    def square(cls, limit_m: float, size_px: int) -> PlaneView:
        """±limit_m on both axes in a size_px square (the devkit's `axes_limit`)."""
        return cls(-limit_m, limit_m, -limit_m, limit_m, size_px / (2.0 * limit_m))

    @classmethod
    def around(cls, xy_min, xy_max, margin_m: float, height_px: int) -> PlaneView:
        """The box (xy_min, xy_max) grown by `margin_m`, `height_px` high (the width follows, equal scale)."""
        x0, y0 = float(xy_min[0]) - margin_m, float(xy_min[1]) - margin_m
        x1, y1 = float(xy_max[0]) + margin_m, float(xy_max[1]) + margin_m
        return cls(x0, x1, y0, y1, height_px / max(y1 - y0, 1e-6))

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return (max(2, int(round((self.x_max - self.x_min) * self.px_per_m))),
                max(2, int(round((self.y_max - self.y_min) * self.px_per_m))))

    def to_pixels(self, xy) -> np.ndarray:
        """(..., 2) plane metres -> (..., 2) pixels."""
        xy = np.asarray(xy, dtype=np.float64)
        s = self.px_per_m
        return np.stack([(xy[..., 0] - self.x_min) * s - 0.5, (self.y_max - xy[..., 1]) * s - 0.5], axis=-1)

    def canvas(self) -> np.ndarray:
        """An empty (H, W, 3) BGR picture in the bird's-eye view's background."""
        width, height = self.size
        image = np.empty((height, width, 3), np.uint8)
        image[:] = BACKGROUND_BGR
        return image

    def map_canvas(self, map_layers, origin_xy, yaw_rad: float) -> np.ndarray:
        """The map under the plane (`bev.MapRaster`: its layers and colours) for a plane whose origin is the global
        point `origin_xy` and whose x axis points at `yaw_rad` (the devkit's flat ego frame)."""
        c, s = np.cos(yaw_rad), np.sin(yaw_rad)
        global_from_plane = np.array([[c, -s], [s, c]])
        corners = np.array([[self.x_min, self.y_min], [self.x_min, self.y_max], [self.x_max, self.y_min],
                            [self.x_max, self.y_max]]) @ global_from_plane.T + np.asarray(origin_xy, np.float64)
        lo, hi = corners.min(axis=0) - 2.0, corners.max(axis=0) + 2.0
        raster = MapRaster.build(map_layers, (lo[0], lo[1], hi[0], hi[1]), self.px_per_m)
        # pixel = scale @ plane_from_global @ (g - origin) + offset
        scale = np.array([[self.px_per_m, 0.0], [0.0, -self.px_per_m]])
        linear = scale @ global_from_plane.T
        offset = np.array([-self.x_min * self.px_per_m - 0.5, self.y_max * self.px_per_m - 0.5])
        world_to_pixel = np.c_[linear, offset - linear @ np.asarray(origin_xy, np.float64)]
        return raster.warp(self.size, world_to_pixel)

    def draw_points(self, image: np.ndarray, xy, colours_rgb, size_px: int = 2) -> None:
        """Points (N, 2) as size_px squares of (N, 3) RGB colours, in the order given (later on top)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if not len(xy):
            return
        # draw_points paints far to near by "depth": a rising rank keeps the order given
        draw.draw_points(image, self.to_pixels(xy), -np.arange(len(xy), dtype=np.float64), size_px=size_px,
                         colors_bgr=draw.rgb_to_bgr(colours_rgb))

    def draw_boxes(self, image: np.ndarray, corners, colours_rgb, width_px: int = 2) -> None:
        """Boxes seen from above: (M, 8, 3) corners in the plane's frame (`Box.corners()` order, z ignored), every
        edge (the front face thicker) and the devkit's heading line from the bottom centre to the bottom front."""
        corners = np.asarray(corners, dtype=np.float64).reshape(-1, 8, 3)
        if not len(corners):
            return
        px = self.to_pixels(corners[..., :2])
        draw.draw_boxes(image, draw.box_segments_px(px), colours_rgb, widths=(width_px, width_px + 1, width_px))
        front = px[:, [2, 3]].mean(axis=1)  # Box.render: mean of corners 2, 3 and of 2, 3, 7, 6
        centre = px[:, [2, 3, 7, 6]].mean(axis=1)
        draw.draw_segments(image, np.stack([centre, front], axis=1), colours_rgb, width_px)

    def draw_arrows(self, image: np.ndarray, start_xy, delta_xy, colours_rgb, thickness: int = 1) -> None:
        """Arrows from (N, 2) points by (N, 2) metres, in (N, 3) RGB colours."""
        start = self.to_pixels(np.asarray(start_xy, np.float64).reshape(-1, 2))
        end = self.to_pixels(np.asarray(start_xy, np.float64).reshape(-1, 2) + np.asarray(delta_xy).reshape(-1, 2))
        tip_px = max(4.0, image.shape[0] / 100)
        for a, b, colour in zip(np.rint(start).astype(int), np.rint(end).astype(int), draw.rgb_to_bgr(colours_rgb)):
            length = float(np.hypot(*(b - a)))
            if length < 1:
                continue
            cv2.arrowedLine(image, tuple(a.tolist()), tuple(b.tolist()), tuple(int(c) for c in colour), thickness,
                            cv2.LINE_AA, tipLength=min(0.5, tip_px / length))

    def draw_ego(self, image: np.ndarray, xy=(0.0, 0.0)) -> None:
        """The devkit's red 'x' where the ego is."""
        u, v = np.rint(self.to_pixels(np.asarray(xy, np.float64))).astype(int).tolist()
        cv2.drawMarker(image, (u, v), EGO_MARKER_BGR, cv2.MARKER_TILTED_CROSS, max(8, image.shape[0] // 60), 2,
                       cv2.LINE_AA)
