"""The 18-value `can_bus` vector of the BEVFormer, UniAD and VAD data converters, exactly as they write it.

Their `_get_can_bus_info` (BEVFormer `tools/data_converter/nuscenes_converter.py`, commit 13db21e; UniAD and
VAD copy it) reads the scene's pose messages and does:

    last_pose = pose_list[0]
    for i, pose in enumerate(pose_list):
        if pose['utime'] > sample_timestamp:
            break
        last_pose = pose
    _ = last_pose.pop('utime')  # useless
    pos = last_pose.pop('pos')
    rotation = last_pose.pop('orientation')
    can_bus.extend(pos)
    can_bus.extend(rotation)
    for key in last_pose.keys():
        can_bus.extend(pose[key])  # 16 elements
    can_bus.extend([0., 0.])

so position and orientation come from the last pose message at or before the sample (the first message when
none is), while the remaining fields (accel, rotation_rate, vel, in the file's key order) come from the loop
variable `pose`: the first message *after* the sample, or the last message when none is after it. A scene
without pose messages (or one the devkit refuses: `NuScenesCanBus.can_blacklist`) gives 18 zeros.
`can_bus` reproduces this; `can_bus_corrected` takes every value from the last message at or before the
sample (null without pose messages).
"""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.can_bus.align import neighbours
from nuparquet.can_bus.blacklists import CAN_BLACKLIST, scene_number
from nuparquet.columns import to_numpy
from nuparquet.errors import InputError
from nuparquet.sources.can_bus import FOLDER

HEAD = ("pos", "orientation")


def can_bus_vectors(samples: pl.DataFrame, poses: pl.DataFrame | None, pose_keys: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(N, 18) `can_bus` as the converters compute it and (N, 18) corrected (NaN rows: no pose messages).

    `samples`: scene_name, timestamp; `poses`: the `can_bus/pose` rows (scene_name, utime, pos, orientation,
    accel, rotation_rate, vel; sorted by scene and utime); `pose_keys`: the pose files' key order.
    """
    n = samples.height
    exact, corrected = np.zeros((n, 18)), np.full((n, 18), np.nan)
    if poses is None or poses.height == 0:
        return exact, corrected
    tail = [k for k in pose_keys if k not in ("utime", *HEAD)]
    for k in (*HEAD, *tail):
        _check_numbers(poses, k)
    stacked = {k: to_numpy(poses[k], _width(poses, k)) for k in (*HEAD, *tail)}
    if sum(v.shape[1] for v in stacked.values()) != 16:
        raise InputError(f"pose messages give {sum(v.shape[1] for v in stacked.values())} values "
                         f"({', '.join(pose_keys)}), not the 16 the converters' vector holds")
    prev_row, next_row = neighbours(samples, poses)
    rows = poses.select("scene_name").with_row_index("_row").group_by("scene_name").agg(
        pl.col("_row").min().alias("_first"), pl.col("_row").max().alias("_last"))
    bounds = samples.select("scene_name").join(rows, on="scene_name", how="left", maintain_order="left")
    has_poses = bounds["_first"].is_not_null().to_numpy()
    first, last_of_scene = bounds["_first"].fill_null(0).to_numpy(), bounds["_last"].fill_null(0).to_numpy()
    last = np.where(prev_row >= 0, prev_row, first)  # the loop's `last_pose`
    after = np.where(next_row >= 0, next_row, last_of_scene)  # the loop's `pose` after `break` or the last
    head = np.concatenate([stacked[k][last] for k in HEAD], axis=1)
    # CAN_BLACKLIST: the devkit's get_messages raises for these scenes, so the converters' `except` gives zeros
    listed = np.array([(scene_number(name) or -1) in CAN_BLACKLIST for name in samples["scene_name"].to_list()])
    usable = has_poses & ~listed
    exact[usable, :16] = np.concatenate([head, *(stacked[k][after] for k in tail)], axis=1)[usable]
    corrected[has_poses, :16] = np.concatenate([head, *(stacked[k][last] for k in tail)], axis=1)[has_poses]
    corrected[has_poses, 16:] = 0.0
    return exact, corrected


def _check_numbers(poses: pl.DataFrame, column: str) -> None:
    """The converters `extend` the vector with each field: a list of numbers, or they fail (a number) or write
    text into it (a string, an object): refused, naming the field and the scenes whose messages hold it."""
    dtype = poses.schema[column]
    if isinstance(dtype, (pl.List, pl.Array)) and dtype.inner.is_numeric():
        return
    scenes = poses.filter(pl.col(column).is_not_null())["scene_name"].unique(maintain_order=True).to_list()
    files = ", ".join(f"{FOLDER}/{scene}_pose.json" for scene in scenes[:3])
    raise InputError(f"{files}{' and others' if len(scenes) > 3 else ''}: pose message field "
                     f"{column!r} holds {dtype} values, not lists of numbers, so the converters' can_bus vector "
                     "(sample_can_bus) cannot be formed from them")


def _width(frame: pl.DataFrame, column: str) -> tuple[int]:
    dtype = frame.schema[column]
    return (dtype.size,) if isinstance(dtype, pl.Array) else (len(frame[column][0]),)
