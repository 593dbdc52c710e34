"""Rigid transforms `X_from_Y`: built from poses, inverted exactly, applied to points (numpy only).

A transform `X_from_Y` is a `(4, 4)` (or stacked `(N, 4, 4)`) row-major matrix that maps homogeneous points in
frame Y to frame X. It is built from the pose of Y expressed in X: `global_from_ego` from an `ego_pose`
record, `ego_from_sensor` from a `calibrated_sensor` record. Chains read like algebra:
`global_from_sensor = global_from_ego @ ego_from_sensor`.
"""

from __future__ import annotations

import numpy as np

from nuparquet.geometry.quaternions import as_float_array, rotation_matrices


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
    translation_m = as_float_array(translation_m, (3,), "translation_m")
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
    X_from_Y = as_float_array(X_from_Y, (4, 4), "X_from_Y")
    Y_from_X_rotation = np.swapaxes(X_from_Y[..., :3, :3], -1, -2)
    Y_from_X = np.zeros_like(X_from_Y)
    Y_from_X[..., :3, :3] = Y_from_X_rotation
    Y_from_X[..., :3, 3] = -np.einsum("...ij,...j->...i", Y_from_X_rotation, X_from_Y[..., :3, 3])
    Y_from_X[..., 3, 3] = 1.0
    return Y_from_X


def apply_linear(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
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
    X_from_Y = as_float_array(X_from_Y, (4, 4), "X_from_Y")
    points_Y = as_float_array(points_Y, (3,), "points_Y")
    translation = X_from_Y[..., :3, 3]
    rotated = apply_linear(X_from_Y[..., :3, :3], points_Y)
    if X_from_Y.ndim > 2 and points_Y.ndim == X_from_Y.ndim:
        translation = translation[..., None, :]
    return rotated + translation
