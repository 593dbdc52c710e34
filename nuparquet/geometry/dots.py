"""Dot products and norms of many small vectors with the rounding of numpy's `np.dot(a, b)` and
`np.linalg.norm(a)` on one vector: the BLAS `ddot` of the machine (numpy only).

The devkit and pyquaternion call `np.dot` / `np.linalg.norm` on one 2- or 4-vector at a time; numpy hands those
to OpenBLAS's `ddot`, whose kernel is chosen by the CPU at start-up (SkylakeX's sums with fused multiply-adds,
Haswell's and Sandybridge's do not), so the last bit of the devkit's own result differs between machines.
`np.matmul` of stacked (1, k) @ (k, 1) matrices calls the same `ddot` for each pair, in C, so these functions
give the devkit's bits on whatever machine runs them, over arrays (about twice the cost of `np.sum(a * b, -1)`).
Use them only where a decision or a bit-equal result depends on the devkit's rounding (docs/CONTRACTS.md).
"""

from __future__ import annotations

import numpy as np


def rowwise_dot(a, b) -> np.ndarray:
    """(...,) the dot product of each pair of rows of (..., k) `a` and `b`, as `np.dot(a[i], b[i])` rounds it."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    a, b = np.broadcast_arrays(a, b)
    return np.matmul(a[..., None, :], b[..., :, None])[..., 0, 0]


def rowwise_norm(a) -> np.ndarray:
    """(...,) the Euclidean norm of each row of (..., k) `a`, as `np.linalg.norm(a[i])` rounds it
    (`sqrt(a . a)`, the dot through BLAS)."""
    return np.sqrt(rowwise_dot(a, a))
