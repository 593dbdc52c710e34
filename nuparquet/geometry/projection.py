"""Projection into images (numpy only): the devkit's `view_points`, the perspective projection of points by
their cameras' intrinsics, pixel rescaling, and the devkit's `box_in_image` rule.

Pixel centres sit at integer coordinates, so resizing an image by s maps u to s * (u + 0.5) - 0.5
(`scale_pixels`, what `cv2.resize` does). "Inside the image" keeps the devkit's meaning on the full-size image
(0 < u < width) whatever the size of the pixels projected to (`pixels_in_image` takes the scale).
"""

from __future__ import annotations

import numpy as np

from nuparquet.geometry.quaternions import as_float_array
from nuparquet.geometry.rigid import apply_linear

# The devkit's near plane: box_in_image drops a box unless every corner is deeper than this, and clipped edges
# stop here (`Cameras.clip_segments`).
NEAR_PLANE_M = 0.1
# box_in_image: a corner counts as visible only if it is also deeper than this.
CORNER_MIN_DEPTH_M = 1.0


def view_points(points, intrinsic, normalize: bool = True) -> np.ndarray:
    """Project points with a view matrix, as devkit `view_points` (which pads the view to 4x4).

    Args:
        points: points in the camera frame, metres. With one view matrix any (..., 3); with a stack of
            (B..., h, w) views (B..., 3) or (B..., K, 3), as in `transform_points`.
        intrinsic: (h, w) or (B..., h, w) view matrix with h, w <= 4 (a 3x3 camera intrinsic for perspective).
        normalize: divide by the third coordinate (perspective projection).

    Returns:
        Projected points, float64, the shape of `points`: [u, v, 1] in pixels when normalised (a point with
        depth 0 gives inf/nan, as in the devkit), [u, v, depth] otherwise.
    """
    points = as_float_array(points, (3,), "points")
    intrinsic = np.asarray(intrinsic, dtype=np.float64)
    rows, cols = intrinsic.shape[-2:]
    if rows > 4 or cols > 4:
        raise ValueError(f"view matrix must be at most 4x4, got {intrinsic.shape[-2:]}")
    viewpad = np.broadcast_to(np.eye(4), intrinsic.shape[:-2] + (4, 4)).copy()
    viewpad[..., :rows, :cols] = intrinsic
    projected = apply_linear(viewpad[..., :3, :3], points)
    translation = viewpad[..., :3, 3]
    if viewpad.ndim > 2 and points.ndim == viewpad.ndim:
        translation = translation[..., None, :]
    projected = projected + translation
    if normalize:
        with np.errstate(divide="ignore", invalid="ignore"):
            projected = projected / projected[..., 2:3]
    return projected


def scale_pixels(points_px, scale) -> np.ndarray:
    """Pixel coordinates of an image -> those of the image resized by `scale` (as `cv2.resize`).

    Pixel centres sit at integer coordinates, so the map is u' = s * (u + 0.5) - 0.5, not u' = s * u.

    Args:
        points_px: (..., 2) [u, v] pixels.
        scale: one factor, (2,) [sx, sy], or (..., 2) broadcasting against `points_px`.
    """
    scale = np.asarray(scale, dtype=np.float64)
    if scale.ndim == 0:
        scale = np.broadcast_to(scale, (2,))
    return np.asarray(points_px, dtype=np.float64) * scale + (scale - 1.0) / 2.0


def scale_intrinsic(image_from_camera, scale) -> np.ndarray:
    """(..., 3, 3) camera matrices of an image -> those of the image resized by `scale` (see `scale_pixels`).

    `scale` is one factor, (2,) [sx, sy], or (..., 2) one pair per matrix.
    """
    scale = np.asarray(scale, dtype=np.float64)
    if scale.ndim == 0:
        scale = np.broadcast_to(scale, (2,))
    sx, sy = scale[..., 0], scale[..., 1]
    resized_from_image = np.zeros(np.shape(sx) + (3, 3))
    resized_from_image[..., 0, 0], resized_from_image[..., 0, 2] = sx, (sx - 1.0) / 2.0
    resized_from_image[..., 1, 1], resized_from_image[..., 1, 2] = sy, (sy - 1.0) / 2.0
    resized_from_image[..., 2, 2] = 1.0
    return resized_from_image @ np.asarray(image_from_camera, dtype=np.float64)


def perspective(image_from_camera, points_camera_m) -> tuple[np.ndarray, np.ndarray]:
    """Perspective projection (devkit `view_points(..., normalize=True)`) of points by their cameras'
    intrinsics: image_from_camera (F, 3, 3) and points (F, 3) or (F, K, 3) in the camera frame, metres.
    Returns pixels [u, v] (the points' shape with 2 coordinates) and depths (camera z, metres); see
    `Cameras.project`."""
    points_camera_m = np.asarray(points_camera_m, dtype=np.float64)
    # view_points' product without its 4x4 padding (a copy of F matrices): the same numbers.
    camera_to_image_t = np.ascontiguousarray(np.swapaxes(image_from_camera, -1, -2))  # matmul is faster on it
    if points_camera_m.ndim == 2:
        projected = (points_camera_m[:, None, :] @ camera_to_image_t)[:, 0]
    else:
        projected = points_camera_m @ camera_to_image_t
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = projected[..., :2] / projected[..., 2:3]
    return uv, points_camera_m[..., 2]


def pixels_in_image(uv, size_px, scale, margin_px: float = 0.0) -> np.ndarray:
    """`Cameras.in_image` for pixels (F, 2) or (F, K, 2) of cameras with (F, 2) image sizes and scales."""
    uv = np.asarray(uv, dtype=np.float64)
    offset = (scale - 1.0) / 2.0  # where the full image's pixel 0 lands (scale_pixels)
    low = margin_px * scale + offset
    high = size_px - margin_px * scale + offset
    if uv.ndim == 3:
        low, high = low[:, None, :], high[:, None, :]
    u, v = uv[..., 0], uv[..., 1]
    return (u > low[..., 0]) & (u < high[..., 0]) & (v > low[..., 1]) & (v < high[..., 1])




def box_visibility(corners_px, depths_m, size_px, scale) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """devkit `box_in_image`, per box: (corner_visible (M, 8), in_front (M,), visible (M,) = BoxVisibility.ANY).

    A corner is visible when it lies inside the image (`pixels_in_image` on the full-size image) and deeper than
    `CORNER_MIN_DEPTH_M`; a box is in front when every corner is deeper than `NEAR_PLANE_M`. BoxVisibility.ALL
    is `corner_visible.all(axis=1) & in_front`.

    Args:
        corners_px: (M, 8, 2) projected corners; depths_m: (M, 8) their camera depths.
        size_px, scale: (M, 2) the image size and scale of each box's camera (`Cameras.size_px`, `.scale`).
    """
    corner_visible = pixels_in_image(corners_px, size_px, scale) & (depths_m > CORNER_MIN_DEPTH_M)
    in_front = np.all(depths_m > NEAR_PLANE_M, axis=1)
    return corner_visible, in_front, np.any(corner_visible, axis=1) & in_front
