"""Reference computations that several tests share, written as their originals are (not by the library)."""

from __future__ import annotations

import numpy as np


def bevformer_can_bus(pose_list: list[dict] | None, sample_timestamp: int) -> np.ndarray:
    """BEVFormer `tools/data_converter/nuscenes_converter.py` (commit 13db21e) `_get_can_bus_info`, as written there:
    `pose_list` is a freshly loaded list of pose messages (the loop pops keys from them), None when the scene has
    none (the converter's `except` branch)."""
    if pose_list is None:
        return np.zeros(18)
    can_bus = []
    last_pose = pose_list[0]
    for i, pose in enumerate(pose_list):
        if pose['utime'] > sample_timestamp:
            break
        last_pose = pose
    _ = last_pose.pop('utime')
    pos = last_pose.pop('pos')
    rotation = last_pose.pop('orientation')
    can_bus.extend(pos)
    can_bus.extend(rotation)
    for key in last_pose.keys():
        can_bus.extend(pose[key])
    can_bus.extend([0., 0.])
    return np.array(can_bus)
