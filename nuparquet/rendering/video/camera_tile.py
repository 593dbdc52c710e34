"""A camera's tile of each output picture (a `render.plan.TileSource`): the camera frame the plan matched to
the output, decoded at the tile size, with its lidar points (if asked) and its boxes drawn on it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from nuparquet.rendering import draw, legend
from nuparquet.rendering.decode import decode_frame, decode_image
from nuparquet.rendering.overlay import LIDAR_MAX_DEPTH_M, DrawStyle, Overlay
from nuparquet.rendering.plan import RowTile, TileLoad

if TYPE_CHECKING:
    from nuparquet.rendering.points import LidarPoints


@dataclass(frozen=True)
class CameraTile(RowTile):
    """One camera channel's tiles.

    label: the channel. rows: (T,) camera row shown at each output (-1: none). paths: (F,) image file of each
    camera row (its filename when `sensors` reads the images the output embeds); decode_scale: (F,) tile size / image size of each row (picks the cheapest JPEG decode).
    """

    label: str
    rows: np.ndarray
    paths: Sequence[str]
    decode_scale: np.ndarray
    tile_size: tuple[int, int]
    overlay: Overlay
    style: DrawStyle
    lidar: LidarPoints | None = None
    image_size_px: np.ndarray | None = None  # (F, 2) width, height of each row's image as its sample_data says
    predictions: Overlay | None = None  # predicted boxes (`render.predictions`), drawn over the ground truth
    prediction_style: DrawStyle | None = None
    tokens: tuple[str, ...] = ()  # (F,) sample_data token of each camera row (the frame index)
    timestamps_us: np.ndarray | None = None  # (F,)
    prediction_legend: tuple = ()  # (name, RGB) entries: what the predictions' colours mean
    sensors: object = None  # the dataset's SensorReader when the output embeds its images (else `paths` are read)

    def load(self, t: int) -> TileLoad:
        row = self.key(t)
        if row is None:
            return TileLoad()
        expected = None if self.image_size_px is None else tuple(int(v) for v in self.image_size_px[row])
        if self.sensors is not None:
            image, _ = decode_frame(self.sensors, self.tokens[row], self.paths[row], self.tile_size,
                                    float(self.decode_scale[row]), expected)
        else:
            image = decode_image(self.paths[row], self.tile_size, float(self.decode_scale[row]), expected)
        if image is None:
            return TileLoad(None, (self.paths[row],))
        points, missing = self.lidar.load(row) if self.lidar is not None else (None, None)
        return TileLoad((image, points), (missing,) if missing else ())

    def draw(self, t: int, loaded: TileLoad) -> np.ndarray | None:
        if loaded.data is None:
            return None
        image, points = loaded.data
        if points is not None:
            draw.draw_points(image, points[0], points[1], max_depth_m=LIDAR_MAX_DEPTH_M,
                             size_px=self.style.point_size_px, colors_bgr=points[2])
        image = self.overlay.draw(image, int(self.rows[t]), self.style)
        if self.predictions is not None:
            self.predictions.draw(image, int(self.rows[t]), self.prediction_style or self.style)
            legend.draw_legend(image, self.prediction_legend, corner="top-right", max_chars=40)
        return image
