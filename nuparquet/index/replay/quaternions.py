"""pyquaternion's arithmetic over arrays of quaternions `(N, 4)` [w, x, y, z], operation for operation, so
that the infos carry the same float64 values the devkit-based converter computes (same products, same
summation order, same normalisation rule)."""

from __future__ import annotations

import math

import numpy as np

from nuparquet.index.replay import blas

_UNIT_TOLERANCE = 1e-14  # pyquaternion's Quaternion.is_unit default


def _sum4(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products over the last axis of length 4, summed left to right like np.dot on 4-vectors."""
    return ((a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]) + a[..., 2] * b[..., 2]) + a[..., 3] * b[..., 3]


def normalised(q: np.ndarray) -> np.ndarray:
    """(N, 4): q / |q| unless |1 - q.q| < 1e-14 (pyquaternion's `_normalise`)."""
    q = np.asarray(q, dtype=np.float64)
    squares = _sum4(q, q)
    norm = np.sqrt(squares)
    scale = ~(np.abs(1.0 - squares) < _UNIT_TOLERANCE) & (norm > 0)
    return np.where(scale[..., None], q / np.where(scale, norm, 1.0)[..., None], q)


def _q_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, -z, y], -1),
                     np.stack([y, z, w, -x], -1), np.stack([z, -y, x, w], -1)], -2)


def _q_bar_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, z, -y], -1),
                     np.stack([y, -z, w, x], -1), np.stack([z, y, -x, w], -1)], -2)


def rotation_matrices(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) `Quaternion(q).rotation_matrix`: q_matrix @ q_bar_matrix.T of the normalised q (a gemm)."""
    q = normalised(q)
    # only the lower-right 3x3 block is kept: its elements are computed alone, each as the gemm computes it
    return blas.gemm(_q_matrix(q)[..., 1:, :], np.swapaxes(_q_bar_matrix(q), -1, -2)[..., :, 1:])


def rough_rotation_matrices(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) the textbook closed form of the rotation matrix: a few ulps from `rotation_matrices`, for
    conservative pre-filters with margins only (never for output values)."""
    w, x, y, z = np.moveaxis(normalised(q), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def inverse(q: np.ndarray) -> np.ndarray:
    """(N, 4) `Quaternion(q).inverse`: the conjugate over q.q (not normalised)."""
    q = np.asarray(q, dtype=np.float64)
    conjugate = q * np.array([1.0, -1.0, -1.0, -1.0])
    return conjugate / _sum4(q, q)[..., None]


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(N, 4) the Hamilton product `p * q` (pyquaternion: np.dot(q_matrix(p), q), a gemv)."""
    return blas.gemv_rows(_q_matrix(np.asarray(p, dtype=np.float64)), np.asarray(q, dtype=np.float64))


def yaw(q: np.ndarray) -> np.ndarray:
    """(N,) `Quaternion(q).yaw_pitch_roll[0]` in radians.

    pyquaternion computes it on numpy scalars: `y ** 2` is the C library's pow (not always y * y) and
    np.arctan2 of scalars in numpy 1.26 is the C library's atan2 (numpy 2's vectorised arctan2 differs in
    the last bit), so both go through `math` here, one scalar at a time (~0.3 us each).
    """
    q = normalised(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    y2 = np.fromiter(map(math.pow, y.ravel().tolist(), [2.0] * y.size), np.float64, y.size).reshape(y.shape)
    z2 = np.fromiter(map(math.pow, z.ravel().tolist(), [2.0] * z.size), np.float64, z.size).reshape(z.shape)
    num, den = 2 * (w * z - x * y), 1 - 2 * (y2 + z2)
    return np.fromiter(map(math.atan2, num.ravel().tolist(), den.ravel().tolist()), np.float64,
                       num.size).reshape(num.shape)
