"""Lidar sweeps of each keyframe: the converter follows `prev` from the keyframe reading up to `max_sweeps`
times, through earlier keyframes too, and lists what the tables name without opening files. Walked for all
samples at once, one step per sweep depth."""

from __future__ import annotations

import numpy as np


def sweep_rows(keyframe_rows: np.ndarray, prev: np.ndarray, max_sweeps: int) -> tuple[np.ndarray, np.ndarray]:
    """(owner (W,), row (W,)): for every sweep, the sample it belongs to and its sample_data row, newest first
    within each sample, samples in order. `keyframe_rows` (S,) is -1 where a sample has no such reading."""
    owners, rows = [], []
    current = keyframe_rows.copy()
    for _ in range(max_sweeps):
        alive = current >= 0
        current = np.where(alive, prev[np.where(alive, current, 0)], -1)
        hit = np.flatnonzero(current >= 0)
        if len(hit) == 0:
            break
        owners.append(hit)
        rows.append(current[hit])
    if not owners:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    owner = np.concatenate(owners)
    row = np.concatenate(rows)
    order = np.argsort(owner, kind="stable")  # stable: depth order (newest first) within a sample
    return owner[order], row[order]
