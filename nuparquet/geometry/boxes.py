"""Cuboids: corners in the devkit's `Box.corners()` order, built from half-axes, and points inside them (numpy only).

Box sizes are `[width, length, height]` (the devkit's `wlh`), metres; orientations quaternions `[w, x, y, z]` or
rotation matrices.
"""

from __future__ import annotations

import numpy as np

from nuparquet.geometry.quaternions import as_float_array, rotation_matrices

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


def box_half_axes(size_wlh_m, rotation_wxyz) -> np.ndarray:
    """(N, 3, 3) the half-axes of boxes in their frame: row j is the box's axis j (x length, y width,
    z height) times half the box's extent along it, from sizes (N, 3) [w, l, h] m and orientations (N, 4)
    quaternions [w, x, y, z] or (N, 3, 3) rotation matrices. `corners_from_half_axes` makes the corners."""
    size_wlh_m = as_float_array(size_wlh_m, (3,), "size_wlh_m")
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
    translation_m = as_float_array(translation_m, (3,), "translation_m")
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
