"""Every box of a render, projected once into the output tiles and ready to draw.

The boxes of every camera row (`frame_boxes`) move into the cameras of the tiles (`Cameras` resized to the
tile size) and are projected there, once for the whole render: drawing then only slices arrays per frame.
Devkit mode keeps the boxes `box_in_image` would draw (BoxVisibility.ANY, tested on the full-size image);
`clip` mode clips each edge at the near plane instead, so boxes partly behind the camera keep their visible part.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.frames.boxes import FramedCuboids
from nuparquet.frames.projection import boxes_in_cameras
from nuparquet.geometry import Cameras, box_visibility, perspective
from nuparquet.rendering.palette import category_rgb
from nuparquet.rendering import draw

LIDAR_MAX_DEPTH_M = 60.0  # colour scale of projected lidar points


@dataclass(frozen=True)
class DrawStyle:
    """Line widths (body, front face, cross), label font scale and point size, in output pixels."""

    widths: tuple[int, int, int]
    font_scale: float
    point_size_px: int

    @classmethod
    def for_scale(cls, scale: float) -> DrawStyle:
        """The style of an output at `scale` times the camera image size (the devkit's at 1)."""
        return cls(draw.line_widths(scale), max(0.3, 0.8 * scale), max(1, round(3 * scale)))


@dataclass(frozen=True)
class Overlay:
    """Every box of the render, ready to draw: sorted by camera row, far to near within a row."""

    segments_px: np.ndarray  # (M, 14, 2, 2) in output-tile pixels
    keep: np.ndarray  # (M, 14)
    colors_rgb: np.ndarray  # (M, 3)
    labels: list[str] | None
    row_start: np.ndarray  # (F + 1,) boxes of camera row f are [row_start[f], row_start[f + 1])

    def draw(self, image_bgr: np.ndarray, row: int, style: DrawStyle) -> np.ndarray:
        """Draw the boxes of camera row `row` onto its tile, in place."""
        start, stop = self.row_start[row], self.row_start[row + 1]
        return draw.draw_boxes(
            image_bgr, self.segments_px[start:stop], self.colors_rgb[start:stop], keep=self.keep[start:stop],
            labels=None if self.labels is None else self.labels[start:stop], widths=style.widths,
            font_scale=style.font_scale,
        )


def category_colors(category_names: np.ndarray) -> np.ndarray:
    """(M,) category names -> (M, 3) uint8 RGB of the devkit palette."""
    names, inverse = np.unique(category_names.astype(str), return_inverse=True)
    palette = np.array([category_rgb(name) for name in names], dtype=np.uint8).reshape(-1, 3)
    return palette[inverse.reshape(-1)] if len(names) else np.zeros((0, 3), dtype=np.uint8)


def segments_touch_image(segments_px: np.ndarray, keep: np.ndarray, size_px: np.ndarray) -> np.ndarray:
    """(M,) True where the bounding box of a box's kept segment end points overlaps its image ((M, 2) sizes).

    Conservative (a box whose outline only surrounds a corner of the image counts too); OpenCV clips what
    lies outside, so a false positive draws nothing extra.
    """
    low, high = draw.segments_extent(segments_px, keep)
    return (keep.any(axis=1) & (high[:, 0] >= 0) & (low[:, 0] <= size_px[:, 0] - 1) & (high[:, 1] >= 0)
            & (low[:, 1] <= size_px[:, 1] - 1))


def build_overlay(tile_cameras: Cameras, boxes: FramedCuboids, *, clip: bool = False,
                  labels: str = "category", visibility: str = "any", colors_rgb: np.ndarray | None = None,
                  texts: list[str] | None = None) -> Overlay:
    """Project every box of every camera row into its tile, once, and order the boxes for drawing.

    Args:
        tile_cameras: (F,) one camera per camera row, resized to the tile (`Cameras.resized_to`).
        boxes: the boxes of those rows (frame_index counts them): `frame_boxes` over the same rows (`FrameBoxes`:
            their categories and instances give the colours and labels), or any `FramedCuboids` with `colors_rgb`
            and `texts`.
        clip: clip edges at the near plane instead of keeping only the boxes the devkit draws.
        labels: "category", "track" or "none".
        visibility: the boxes the devkit draws (without `clip`): "any" (BoxVisibility.ANY) or "all" (every corner
            in the image); "none" (every box, BoxVisibility.NONE) draws each box's part in front of the near plane,
            as `clip` does, rather than the mirrored projection of corners behind the camera.
        colors_rgb, texts: (M,) colours and labels of the boxes instead of the category's (predicted boxes).
    """
    frame = boxes.frame_index
    seen = boxes_in_cameras(tile_cameras, boxes)
    if visibility not in ("any", "all", "none"):
        raise ValueError(f"visibility must be any, all or none, got {visibility!r}")
    clip = clip or visibility == "none"
    if clip:
        cameras = tile_cameras.take(frame)  # clip_segments projects each box with its own camera
        segments_px, keep = cameras.clip_segments(seen.corners_camera_m[:, draw.BOX_SEGMENT_CORNERS])
        shown = segments_touch_image(segments_px, keep, cameras.size_px)
    else:
        corners_px, depths = perspective(tile_cameras.image_from_camera[frame], seen.corners_camera_m)
        corner_visible, in_front, shown = box_visibility(corners_px, depths, tile_cameras.size_px[frame],
                                                         tile_cameras.scale[frame])
        if visibility == "all":
            shown = corner_visible.all(axis=1) & in_front
        segments_px = draw.box_segments_px(corners_px)
        keep = np.ones(segments_px.shape[:2], dtype=bool)
    distance_m = np.linalg.norm(seen.center_camera_m, axis=1)
    order = np.lexsort((-distance_m, frame))  # by camera row, then far to near
    order = order[shown[order]]
    if texts is not None:
        texts = [texts[i] for i in order.tolist()]
    elif labels == "category":
        texts = [draw.short_category(name) for name in boxes.category_name[order].tolist()]
    elif labels == "track":
        texts = [draw.short_track(token) for token in boxes.instance_token[order].tolist()]
    else:
        texts = None
    return Overlay(
        segments_px=segments_px[order],
        keep=keep[order],
        colors_rgb=category_colors(boxes.category_name[order]) if colors_rgb is None else colors_rgb[order],
        labels=texts,
        row_start=np.searchsorted(frame[order], np.arange(len(tile_cameras) + 1), side="left"),
    )
