"""Between two samples: centres interpolated as `np.interp` and the slerp amount, as the devkit's `get_boxes`
computes them (numpy only; the slerp itself is `quaternions.quaternion_slerp`); and the record nearest a time, as
truckscenes-devkit's `getclosest` finds it."""

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


def closest_rows(timestamps_us: np.ndarray, query_timestamps_us: np.ndarray) -> np.ndarray:
    """(Q,) the row of the record nearest each query time, as truckscenes-devkit's `getclosest(table, t)` picks it
    (ego_pose, ego_motion_*): a tie between an earlier and a later record goes to the earlier; among records
    sharing one timestamp, the last in file order (the devkit keys a dict by timestamp: the last one written wins).
    `timestamps_us`: (P,) the table's timestamps in file order (P >= 1)."""
    return ClosestRows(timestamps_us)(query_timestamps_us)


class ClosestRows:
    """`closest_rows` with the table's timestamps sorted once, for many separate queries (the devkit-style
    `TruckScenes.getclosest`, one time per call)."""

    def __init__(self, timestamps_us: np.ndarray):
        order = np.argsort(timestamps_us, kind="stable")
        times = timestamps_us[order]
        self.distinct, last = np.unique(times[::-1], return_index=True)  # each timestamp's last row in sorted order
        self.last_row = order[len(times) - 1 - last]

    def __call__(self, query_timestamps_us: np.ndarray) -> np.ndarray:
        distinct = self.distinct
        pos = np.searchsorted(distinct, query_timestamps_us, side="left")  # bisect_left
        before = np.clip(pos - 1, 0, len(distinct) - 1)
        after = np.clip(pos, 0, len(distinct) - 1)
        take_after = (pos == 0) | ((pos < len(distinct))
                                   & (distinct[after] - query_timestamps_us < query_timestamps_us - distinct[before]))
        return self.last_row[np.where(take_after, after, before)]
