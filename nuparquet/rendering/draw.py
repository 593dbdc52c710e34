"""Overlays on camera images (numpy BGR arrays, drawn with OpenCV, headless): 3D box wireframes, labels, lidar
points and placeholders for missing images. Drawing only: every input is already in the image's pixels (the
camera model, `nuparquet.geometry.Cameras`, projects and clips).

A box is drawn as 14 segments — the 12 cuboid edges plus a cross on the front face — given as
`(M, 14, 2, 2)` pixel end points (box, segment, end, u/v); `BOX_SEGMENT_CORNERS` says which corners each
segment joins (`box_segments_px` gathers them from projected corners).

`draw_boxes` draws boxes in the order given; pass them far to near so that near boxes end up on top.
Colours are given as RGB (the devkit palette's order) and converted to OpenCV's BGR here.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import cv2
import numpy as np

# Corner index pairs of the drawn segments, in the devkit's corner order (geometry.box_corners): 0-3 front
# face, 4-7 back face. Segments 0-3 outline the front face (drawn thicker), 4-11 are the back face and the
# four sides, 12-13 the diagonals of the front face (the "cross" that says which way the box faces).
BOX_SEGMENT_CORNERS = np.array(
    [
        [0, 1], [1, 2], [2, 3], [3, 0],  # front face
        [4, 5], [5, 6], [6, 7], [7, 4],  # back face
        [0, 4], [1, 5], [2, 6], [3, 7],  # sides
        [0, 2], [1, 3],                  # front cross
    ],
    dtype=np.intp,
)
FRONT_SEGMENTS = slice(0, 4)
BODY_SEGMENTS = slice(4, 12)
CROSS_SEGMENTS = slice(12, 14)

_SHIFT = 4  # sub-pixel bits for cv2 drawing: coordinates are passed as round(x * 16)
_MAX_ABS_PX = 1e6  # clamp before the fixed-point conversion (int32 headroom); cv2 clips lines to the image

TEXT_FONT = cv2.FONT_HERSHEY_SIMPLEX


def rgb_to_bgr(colors_rgb) -> np.ndarray:
    """(..., 3) RGB -> (..., 3) BGR, uint8."""
    return np.asarray(colors_rgb, dtype=np.uint8)[..., ::-1]


def box_segments_px(corners_px) -> np.ndarray:
    """(M, 8, 2) projected corners -> (M, 14, 2, 2) segment end points in pixels (see BOX_SEGMENT_CORNERS)."""
    corners_px = np.asarray(corners_px, dtype=np.float64)
    return corners_px[:, BOX_SEGMENT_CORNERS, :]


def segments_extent(segments_px, keep) -> tuple[np.ndarray, np.ndarray]:
    """(M, 2) low and high corner of the bounding box of each box's kept end points (+inf / -inf if none)."""
    usable = keep[..., None, None] & np.isfinite(segments_px)
    ends = 2 * segments_px.shape[1]  # segments x 2 ends
    points = segments_px.reshape(len(segments_px), ends, 2)
    usable = usable.reshape(len(segments_px), ends, 2)
    low = np.where(usable, points, np.inf).min(axis=1)
    high = np.where(usable, points, -np.inf).max(axis=1)
    return low, high


def _fixed_point(segments_px: np.ndarray) -> np.ndarray:
    """Float pixel coordinates -> int32 with _SHIFT fractional bits, clamped so the conversion cannot overflow."""
    clamped = np.clip(segments_px, -_MAX_ABS_PX, _MAX_ABS_PX)
    return np.rint(clamped * (1 << _SHIFT)).astype(np.int32)


def line_widths(scale: float) -> tuple[int, int, int]:
    """(body, front face, cross) line widths in pixels for an image resized by `scale` (devkit: 2 at full size)."""
    body = max(1, round(2 * scale + 0.01))
    return body, body + 1, max(1, body - 1)


def draw_boxes(
    image_bgr: np.ndarray,
    segments_px: np.ndarray,
    colors_rgb,
    *,
    keep: np.ndarray | None = None,
    labels: Sequence[str] | None = None,
    widths: tuple[int, int, int] = (2, 3, 1),
    font_scale: float = 0.5,
    antialias: bool = True,
) -> np.ndarray:
    """Draw box wireframes in place, in the order given (pass them far to near: later boxes cover earlier ones).

    Args:
        image_bgr: (H, W, 3) uint8 image, modified in place and returned.
        segments_px: (M, 14, 2, 2) segment end points in pixels (`box_segments_px` / `Cameras.clip_segments`).
        colors_rgb: (M, 3) RGB colour of each box.
        keep: optional (M, 14) bool: segments to draw (False for clipped-away segments).
        labels: optional M strings drawn at the top-left of each box; None or "" draws none.
        widths: line widths (body, front face, cross) in pixels.
        font_scale: OpenCV font scale of the labels.
        antialias: cv2.LINE_AA instead of cv2.LINE_8.
    """
    count = len(segments_px)
    if count == 0:
        return image_bgr
    colors_bgr = rgb_to_bgr(colors_rgb).reshape(count, 3)
    keep = np.ones(segments_px.shape[:2], dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    fixed = _fixed_point(np.nan_to_num(segments_px, nan=0.0))
    line_type = cv2.LINE_AA if antialias else cv2.LINE_8
    body_width, front_width, cross_width = widths

    # Consecutive boxes of one colour are drawn by one polylines call per part; the order between runs (far
    # to near) is kept, and within a run the colour is the same, so merging changes nothing visible.
    changes = np.flatnonzero(np.any(colors_bgr[1:] != colors_bgr[:-1], axis=1)) + 1
    run_starts = np.concatenate([[0], changes])
    run_ends = np.concatenate([changes, [count]])
    for start, stop in zip(run_starts.tolist(), run_ends.tolist()):
        color = tuple(int(c) for c in colors_bgr[start])
        for part, width in ((BODY_SEGMENTS, body_width), (CROSS_SEGMENTS, cross_width), (FRONT_SEGMENTS, front_width)):
            lines = fixed[start:stop, part][keep[start:stop, part]]  # (K, 2, 2)
            if len(lines):
                cv2.polylines(image_bgr, list(lines), False, color, width, line_type, _SHIFT)

    if labels is not None:
        draw_labels(image_bgr, segments_px, keep, labels, colors_bgr, font_scale=font_scale)
    return image_bgr


def draw_segments(image_bgr: np.ndarray, segments_px, colors_rgb, width: int = 2, antialias: bool = True) -> np.ndarray:
    """Draw (K, 2, 2) line segments (start, end; u, v pixels) in (K, 3) RGB colours, in place; one polylines call
    per colour."""
    segments_px = np.asarray(segments_px, dtype=np.float64).reshape(-1, 2, 2)
    if not len(segments_px):
        return image_bgr
    fixed = _fixed_point(np.nan_to_num(segments_px, nan=0.0))
    colors_bgr = rgb_to_bgr(colors_rgb).reshape(-1, 3)
    unique, inverse = np.unique(colors_bgr, axis=0, return_inverse=True)
    for k, color in enumerate(unique):
        cv2.polylines(image_bgr, list(fixed[inverse.reshape(-1) == k]), False, tuple(int(c) for c in color), width,
                      cv2.LINE_AA if antialias else cv2.LINE_8, _SHIFT)
    return image_bgr


def draw_labels(image_bgr, segments_px, keep, labels, colors_bgr, *, font_scale: float = 0.5) -> np.ndarray:
    """Label each box at the top-left of its projected outline, kept inside the image; text on a box-coloured
    background, black or white, whichever reads better. Boxes whose label is empty are skipped."""
    height, width = image_bgr.shape[:2]
    thickness = max(1, round(font_scale * 2))
    top_left, _ = segments_extent(segments_px, keep)  # (M, 2); inf for boxes with nothing kept
    luminance = colors_bgr.astype(np.float64) @ np.array([0.114, 0.587, 0.299])
    # One putText per label: text cannot be batched, and the label count per frame is small.
    for index, text in enumerate(labels):
        if not text or not np.all(np.isfinite(top_left[index])):
            continue
        (text_w, text_h), baseline = _text_size(text, font_scale, thickness)
        x = int(np.clip(top_left[index, 0], 0, max(0, width - text_w - 2)))
        y = int(np.clip(top_left[index, 1], text_h + baseline + 2, height - 1))
        color = tuple(int(c) for c in colors_bgr[index])
        cv2.rectangle(image_bgr, (x, y - text_h - baseline - 2), (x + text_w + 2, y), color, cv2.FILLED)
        ink = (0, 0, 0) if luminance[index] > 128 else (255, 255, 255)
        cv2.putText(image_bgr, text, (x + 1, y - baseline - 1), TEXT_FONT, font_scale, ink, thickness, cv2.LINE_AA)
    return image_bgr


def start_text() -> None:
    """Start OpenCV's text engine on this thread: OpenCV 5 sets it up per thread on the first text call, ~30-80 ms
    (more than the drawing of a 40-frame video's labels), so the render does it while its query runs elsewhere."""
    cv2.getTextSize("0", TEXT_FONT, 1.0, 1)


@lru_cache(maxsize=4096)
def _text_size(text: str, font_scale: float, thickness: int) -> tuple[tuple[int, int], int]:
    """cv2.getTextSize of a label: labels repeat on every frame (a few categories, a few hundred tracks)."""
    return cv2.getTextSize(text, TEXT_FONT, font_scale, thickness)


def short_category(name: str) -> str:
    """A label for a category: the name without its top-level group ("vehicle.car" -> "car",
    "human.pedestrian.adult" -> "pedestrian.adult", "animal" -> "animal")."""
    head, _, rest = name.partition(".")
    return rest or head


def short_track(instance_token: str, length: int = 6) -> str:
    """A label for a track: the first characters of its instance token."""
    return instance_token[:length]


def draw_points(
    image_bgr: np.ndarray,
    points_px,
    depths_m,
    *,
    max_depth_m: float = 60.0,
    size_px: int = 2,
    colormap: int = cv2.COLORMAP_TURBO,
    colors_bgr=None,
) -> np.ndarray:
    """Draw projected points as small squares coloured by depth (near red, far blue), or by `colors_bgr` ((N, 3)
    uint8, e.g. lidarseg classes) when given, far to near, in place.

    Args:
        image_bgr: (H, W, 3) uint8.
        points_px: (N, 2) pixel coordinates.
        depths_m: (N,) depth of each point; the colour scale spans 0..max_depth_m (farther points clip).
        size_px: side of each square.
    """
    points_px = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    depths_m = np.asarray(depths_m, dtype=np.float64).reshape(-1)
    if len(points_px) == 0:
        return image_bgr
    height, width = image_bgr.shape[:2]
    order = np.argsort(-depths_m, kind="stable")  # far first, so near points are written last
    points_px, depths_m = points_px[order], depths_m[order]
    if colors_bgr is None:
        levels = np.rint(255.0 * (1.0 - np.clip(depths_m / max_depth_m, 0.0, 1.0))).astype(np.uint8)
        colors_bgr = cv2.applyColorMap(levels.reshape(-1, 1), colormap).reshape(-1, 3)
    else:
        colors_bgr = np.asarray(colors_bgr, dtype=np.uint8).reshape(-1, 3)[order]
    offsets = np.arange(size_px) - (size_px - 1) // 2
    u = np.rint(points_px[:, 0]).astype(np.int64)[:, None, None] + offsets[None, None, :]
    v = np.rint(points_px[:, 1]).astype(np.int64)[:, None, None] + offsets[None, :, None]
    u, v = np.broadcast_arrays(u, v)
    inside = (u >= 0) & (u < width) & (v >= 0) & (v < height)
    colors = np.broadcast_to(colors_bgr[:, None, None, :], u.shape + (3,))
    image_bgr[v[inside], u[inside]] = colors[inside]
    return image_bgr


def placeholder(width: int, height: int, text: str) -> np.ndarray:
    """A dark grey (height, width, 3) image with `text` centred: stands in for a missing camera image."""
    image = np.full((height, width, 3), 48, dtype=np.uint8)
    font_scale = max(0.3, width / 1600)
    thickness = max(1, round(font_scale * 2))
    (text_w, text_h), _ = cv2.getTextSize(text, TEXT_FONT, font_scale, thickness)
    origin = (max(0, (width - text_w) // 2), (height + text_h) // 2)
    cv2.putText(image, text, origin, TEXT_FONT, font_scale, (200, 200, 200), thickness, cv2.LINE_AA)
    return image
