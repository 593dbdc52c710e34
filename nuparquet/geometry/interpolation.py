"""Between two samples: centres interpolated as `np.interp` and the slerp amount, as the devkit's `get_boxes`
computes them (numpy only; the slerp itself is `quaternions.quaternion_slerp`)."""

from __future__ import annotations

import numpy as np


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
