"""Rigid-body geometry for nuScenes data, vectorised over boxes and frames (numpy only).

Conventions follow nuscenes-devkit and pyquaternion exactly, so results can be checked against them:

- Quaternions are arrays `[..., 4]` in `[w, x, y, z]` order (the nuScenes JSON order).
- A transform `X_from_Y` is a `(4, 4)` (or stacked `(N, 4, 4)`) row-major matrix that maps homogeneous
  points in frame Y to frame X. It is built from the pose of Y expressed in X: `global_from_ego` from an
  `ego_pose` record, `ego_from_sensor` from a `calibrated_sensor` record. Chains read like algebra:
  `global_from_sensor = global_from_ego @ ego_from_sensor`.
- Lengths are metres, box sizes are `[width, length, height]` (the devkit's `wlh`), angles are radians.

Nothing here reads files, knows polars or draws: the inputs are plain arrays.
"""

from __future__ import annotations

import numpy as np

from nuparquet.quaternions import as_float_array as _as_float_array, rotation_matrices

# Corner signs of a box in its own frame, in the order of devkit Box.corners(): x forward, y left, z up;
# the first four corners form the front face (x = +l/2), the last four the back face.
_CORNER_SIGNS_XYZ = np.array(
    [
        [1, 1, 1, 1, -1, -1, -1, -1],
        [1, -1, -1, 1, 1, -1, -1, 1],
        [1, 1, -1, -1, 1, 1, -1, -1],
    ],
    dtype=np.float64,
).T.copy()  # (8, 3), contiguous for the stacked product


def rigid_transforms(translation_m, rotation_wxyz) -> np.ndarray:
    """4x4 transforms X_from_Y from the pose of frame Y expressed in frame X.

    `rigid_transforms(ego_pose.translation, ego_pose.rotation)` is `global_from_ego`;
    `rigid_transforms(calibrated_sensor.translation, calibrated_sensor.rotation)` is `ego_from_sensor`.

    Args:
        translation_m: (..., 3) origin of Y in X, metres.
        rotation_wxyz: (..., 4) orientation of Y in X, quaternion [w, x, y, z].

    Returns:
        (..., 4, 4) float64 homogeneous transforms mapping points in Y to X.
    """
    translation_m = _as_float_array(translation_m, (3,), "translation_m")
    rotation = rotation_matrices(rotation_wxyz)
    batch = np.broadcast_shapes(translation_m.shape[:-1], rotation.shape[:-2])
    X_from_Y = np.zeros(batch + (4, 4))
    X_from_Y[..., :3, :3] = rotation
    X_from_Y[..., :3, 3] = translation_m
    X_from_Y[..., 3, 3] = 1.0
    return X_from_Y


def invert_rigid(X_from_Y) -> np.ndarray:
    """The inverse of rigid transforms, exactly (transpose of the rotation), not by a general matrix inverse.

    Args:
        X_from_Y: (..., 4, 4) rigid transforms.

    Returns:
        (..., 4, 4) float64 transforms Y_from_X.
    """
    X_from_Y = _as_float_array(X_from_Y, (4, 4), "X_from_Y")
    Y_from_X_rotation = np.swapaxes(X_from_Y[..., :3, :3], -1, -2)
    Y_from_X = np.zeros_like(X_from_Y)
    Y_from_X[..., :3, :3] = Y_from_X_rotation
    Y_from_X[..., :3, 3] = -np.einsum("...ij,...j->...i", Y_from_X_rotation, X_from_Y[..., :3, 3])
    Y_from_X[..., 3, 3] = 1.0
    return Y_from_X


def _apply_linear(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """matrix (B..., 3, 3) applied to points (B..., 3) or (B..., K, 3); a single (3, 3) to any (..., 3)."""
    if matrix.ndim == 2:
        return points @ matrix.T
    if points.ndim == matrix.ndim - 1:  # one point per matrix
        return np.einsum("...ij,...j->...i", matrix, points)
    if points.ndim == matrix.ndim:  # K points per matrix: (K, 3) @ (3, 3)^T per batch item
        return points @ np.swapaxes(matrix, -1, -2)
    raise ValueError(
        f"points of shape {points.shape} do not fit transforms of shape {matrix.shape[:-2]} + (4, 4): "
        "expected (B..., 3) or (B..., K, 3)"
    )


def transform_points(X_from_Y, points_Y) -> np.ndarray:
    """Move points from frame Y to frame X.

    Args:
        X_from_Y: (4, 4) one transform, or (B..., 4, 4) a stack.
        points_Y: points in Y, metres. With one transform any (..., 3). With a stack either (B..., 3), one
            point per transform, or (B..., K, 3), K points per transform (e.g. (N, 8, 3) box corners).

    Returns:
        Points in X, float64, the shape of `points_Y`.
    """
    X_from_Y = _as_float_array(X_from_Y, (4, 4), "X_from_Y")
    points_Y = _as_float_array(points_Y, (3,), "points_Y")
    translation = X_from_Y[..., :3, 3]
    rotated = _apply_linear(X_from_Y[..., :3, :3], points_Y)
    if X_from_Y.ndim > 2 and points_Y.ndim == X_from_Y.ndim:
        translation = translation[..., None, :]
    return rotated + translation


def box_half_axes(size_wlh_m, rotation_wxyz) -> np.ndarray:
    """(N, 3, 3) the half-axes of boxes in their frame: row j is the box's axis j (x length, y width,
    z height) times half the box's extent along it, from sizes (N, 3) [w, l, h] m and orientations (N, 4)
    quaternions [w, x, y, z] or (N, 3, 3) rotation matrices. `corners_from_half_axes` makes the corners."""
    size_wlh_m = _as_float_array(size_wlh_m, (3,), "size_wlh_m")
    rotation = np.asarray(rotation_wxyz, dtype=np.float64)
    F_from_box_rotation = rotation if rotation.shape[-2:] == (3, 3) else rotation_matrices(rotation)
    half_lwh = size_wlh_m[..., [1, 0, 2]] / 2.0  # box x is length, y is width, z is height
    return np.swapaxes(F_from_box_rotation, -1, -2) * half_lwh[..., :, None]


def corners_from_half_axes(half_axes) -> np.ndarray:
    """(N, 3, 3) half-axes (`box_half_axes`) -> (N, 8, 3) corners about the box centre, in `box_corners`
    order: each corner is a signed sum of the three half-axes."""
    return _CORNER_SIGNS_XYZ @ np.ascontiguousarray(half_axes, dtype=np.float64)  # (8, 3) @ (N, 3, 3) -> (N, 8, 3)


def box_corners(translation_m, size_wlh_m, rotation_wxyz) -> np.ndarray:
    """The 8 corners of boxes, in the order of devkit `Box.corners()` (transposed).

    Args:
        translation_m: (N, 3) box centres, metres, in some frame F.
        size_wlh_m: (N, 3) box sizes [width, length, height], metres.
        rotation_wxyz: (N, 4) box orientations in F, quaternion [w, x, y, z]; or (N, 3, 3) rotation matrices.

    Returns:
        (N, 8, 3) float64 corners in F. Corners 0-3 are the front face (+x of the box, in the direction of
        travel): top-left, top-right, bottom-right, bottom-left seen from the front; corners 4-7 the back
        face in the same order.
    """
    translation_m = _as_float_array(translation_m, (3,), "translation_m")
    return corners_from_half_axes(box_half_axes(size_wlh_m, rotation_wxyz)) + translation_m[..., None, :]


def count_points_in_boxes(corners, points) -> np.ndarray:
    """(B,) int64: how many of `points` lie in each box, as devkit `points_in_box(box, points).sum()` (faces
    included, the same float64 arithmetic: offsets from corner 0 dotted with the edges to corners 4, 1, 3).

    Vectorised over all (box, point) pairs that pass a cheap test first: points sorted by x once, each box's
    x range found by binary search, then its y/z range, then the exact test on the few pairs left.

    Args:
        corners: (B, 8, 3) box corners in `Box.corners()` order (`box_corners`), in the points' frame.
        points: (P, 3) points (any float type).
    """
    corners = np.asarray(corners, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    if not len(corners) or not len(points):
        return np.zeros(len(corners), dtype=np.int64)
    lo, hi = corners.min(axis=1), corners.max(axis=1)  # (B, 3) axis-aligned bounds: a superset of the box
    order = np.argsort(points[:, 0], kind="stable")
    xs = points[order, 0]
    first, last = np.searchsorted(xs, lo[:, 0], "left"), np.searchsorted(xs, hi[:, 0], "right")
    n = np.maximum(last - first, 0)
    box = np.repeat(np.arange(len(corners)), n)
    offset = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    point = order[np.repeat(first, n) + offset]
    near = ((points[point, 1:] >= lo[box, 1:]) & (points[point, 1:] <= hi[box, 1:])).all(axis=1)
    box, point = box[near], point[near]
    p1 = corners[box, 0]
    v = points[point] - p1  # (K, 3), subtracted first as the devkit does
    inside = np.ones(len(box), dtype=bool)
    for corner in (4, 1, 3):
        edge = corners[box, corner] - p1
        along = np.einsum("kc,kc->k", edge, v)
        inside &= (along >= 0) & (along <= np.einsum("kc,kc->k", edge, edge))
    return np.bincount(box[inside], minlength=len(corners)).astype(np.int64)


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
    points = _as_float_array(points, (3,), "points")
    intrinsic = np.asarray(intrinsic, dtype=np.float64)
    rows, cols = intrinsic.shape[-2:]
    if rows > 4 or cols > 4:
        raise ValueError(f"view matrix must be at most 4x4, got {intrinsic.shape[-2:]}")
    viewpad = np.broadcast_to(np.eye(4), intrinsic.shape[:-2] + (4, 4)).copy()
    viewpad[..., :rows, :cols] = intrinsic
    projected = _apply_linear(viewpad[..., :3, :3], points)
    translation = viewpad[..., :3, 3]
    if viewpad.ndim > 2 and points.ndim == viewpad.ndim:
        translation = translation[..., None, :]
    projected = projected + translation
    if normalize:
        with np.errstate(divide="ignore", invalid="ignore"):
            projected = projected / projected[..., 2:3]
    return projected


def interp_two_points(t, t0, t1, c0, c1) -> np.ndarray:
    """`np.interp(t, [t0, t1], [c0, c1])` per row, with numpy's own formula and end cases, so interpolated
    centres match the devkit's (`NuScenes.get_boxes`) to the last bit: c1 at t == t1, c0 at t == t0, else
    c0 + slope * (t - t0).

    Args:
        t, t0, t1: (N,) times (int64 microseconds) with t0 <= t <= t1.
        c0, c1: (N, k) values at t0 and t1.

    Returns:
        (N, k) float64.
    """
    t, t0, t1 = (np.asarray(a, dtype=np.float64)[:, None] for a in (t, t0, t1))
    c0, c1 = np.asarray(c0, dtype=np.float64), np.asarray(c1, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # the end cases are taken from c0, c1
        slope = (c1 - c0) / (t1 - t0)
        inside = slope * (t - t0) + c0
    return np.where(t == t1, c1, np.where(t == t0, c0, inside))


def slerp_amount(t, t0, t1) -> np.ndarray:
    """(N,) float64 (t - t0) / (t1 - t0), the devkit's slerp amount between two samples; 1 where t1 == t0.

    The devkit divides Python ints; microsecond timestamps are exact in float64, so this rounds the same.
    """
    t, t0, t1 = (np.asarray(a, dtype=np.int64) for a in (t, t0, t1))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(t1 != t0, (t - t0).astype(np.float64) / (t1 - t0).astype(np.float64), 1.0)
