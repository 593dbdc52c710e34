"""The BEVFormer-family `can_bus` vector at its edges, against BEVFormer's own loop as written
(`tools/data_converter/nuscenes_converter.py`, `_get_can_bus_info`, commit 13db21e): a pose message exactly at a
sample's time, samples before the first and after the last message, and a scene on the devkit's CAN bus blacklist
that has pose messages."""

from __future__ import annotations

import copy

import numpy as np
import polars as pl
import pytest

from nuparquet.can_bus.bevformer import can_bus_vectors
from nuparquet.errors import InputError

KEYS = ["utime", "pos", "orientation", "accel", "rotation_rate", "vel"]  # the pose files' key order


def _message(utime: int, k: float) -> dict:
    return {"utime": utime, "pos": [k, k + 0.1, k + 0.2], "orientation": [1.0, k / 100, 0.0, 0.0],
            "accel": [k + 1, k + 2, k + 3], "rotation_rate": [k + 4, k + 5, k + 6], "vel": [k + 7, k + 8, k + 9]}


def bevformer_can_bus(pose_list: list[dict], sample_timestamp: int, blacklisted: bool) -> list[float]:
    """BEVFormer's `_get_can_bus_info`, statement for statement (its try/except gives zeros when the devkit's
    get_messages raises, which it does for blacklisted scenes)."""
    if blacklisted or not pose_list:
        return [0.0] * 18
    pose_list = copy.deepcopy(pose_list)
    can_bus = []
    last_pose = pose_list[0]
    for i, pose in enumerate(pose_list):
        if pose["utime"] > sample_timestamp:
            break
        last_pose = pose
    _ = last_pose.pop("utime")  # useless
    pos = last_pose.pop("pos")
    rotation = last_pose.pop("orientation")
    can_bus.extend(pos)
    can_bus.extend(rotation)
    for key in last_pose.keys():
        can_bus.extend(pose[key])  # 16 elements
    can_bus.extend([0.0, 0.0])
    return can_bus


def _poses(scene: str, messages: list[dict]) -> pl.DataFrame:
    return pl.DataFrame({"scene_name": [scene] * len(messages), **{k: [m[k] for m in messages] for k in KEYS}},
                        schema_overrides={k: pl.Array(pl.Float64, 4 if k == "orientation" else 3) for k in KEYS[1:]})


@pytest.mark.parametrize("scene, blacklisted", [("scene-0001", False), ("scene-0161", True)])
def test_the_vector_equals_bevformers_loop_at_exact_times_before_the_first_and_after_the_last(scene, blacklisted):
    messages = [_message(t, k) for k, t in enumerate([1_000, 2_000, 3_000, 4_000])]
    # before the first message, exactly at one (its head, the next one's tail), between two, exactly at the
    # last (nothing after it: the loop ends on it), after the last
    times = [500, 2_000, 2_500, 4_000, 9_000]
    samples = pl.DataFrame({"scene_name": [scene] * len(times), "timestamp": times})
    exact, corrected = can_bus_vectors(samples, _poses(scene, messages), KEYS)
    for row, t in enumerate(times):
        assert exact[row].tolist() == bevformer_can_bus(messages, t, blacklisted), t
    # at exactly 2_000: position from the message at 2_000, the rest from the message at 3_000 (the loop's `pose`)
    if not blacklisted:
        assert exact[1, :3].tolist() == messages[1]["pos"] and exact[1, 7:10].tolist() == messages[2]["accel"]
    # the corrected vector takes every value from the last message at or before the sample, blacklist or not
    assert corrected[1, 7:10].tolist() == messages[1]["accel"] and corrected[0, :3].tolist() == messages[0]["pos"]
    assert not np.isnan(corrected).any()


def test_a_scene_without_pose_messages_gives_zeros_and_no_corrected_vector():
    samples = pl.DataFrame({"scene_name": ["scene-0002", "scene-0001"], "timestamp": [10, 1_500]})
    exact, corrected = can_bus_vectors(samples, _poses("scene-0001", [_message(1_000, 0.0)]), KEYS)
    assert exact[0].tolist() == [0.0] * 18 and np.isnan(corrected[0]).all()
    assert exact[1].tolist() == bevformer_can_bus([_message(1_000, 0.0)], 1_500, False)


def test_pose_messages_of_another_width_are_refused_naming_the_count_and_the_keys():
    """The converters' vector holds 16 pose values (pos 3, orientation 4, accel, rotation_rate, vel 3 each): pose
    files without `vel` give 13, which must be refused, not silently padded."""
    keys = KEYS[:-1]
    poses = _poses("scene-0001", [_message(1_000, 0.0)]).drop("vel")
    samples = pl.DataFrame({"scene_name": ["scene-0001"], "timestamp": [1_500]})
    with pytest.raises(InputError, match=r"^pose messages give 13 values \(utime, pos, orientation, accel, "
                                         r"rotation_rate\), not the 16 the converters' vector holds$"):
        can_bus_vectors(samples, poses, keys)
