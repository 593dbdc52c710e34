"""CAN bus queries against plain Python over the message files (real extract and synthetic)."""

from __future__ import annotations

import json
import math
from collections import defaultdict

import polars as pl
import pytest

import nuparquet
from conftest import EXTRACT_VERSION, SYNTH_VERSION
from nuparquet.queries import can_bus


@pytest.fixture(scope="module", params=["extract", "synth"])
def case(request):
    if request.param == "extract":
        root, version, out = request.getfixturevalue("extract_root"), EXTRACT_VERSION, request.getfixturevalue("extract_out")
    else:
        root, version, out = request.getfixturevalue("synth_root"), SYNTH_VERSION, request.getfixturevalue("synth_out")
    return root, version, nuparquet.open(out)


def _messages(root, message):
    out = {}
    for path in sorted((root / "can_bus").glob(f"scene-*_{message}.json")):
        out[path.name.split("_")[0]] = json.loads(path.read_text())
    return out


def _lidar_speeds(root, version):
    """Per scene: speeds between consecutive LIDAR_TOP keyframe ego poses (3D step / dt), from the JSON."""
    t = {n: json.loads((root / version / f"{n}.json").read_text()) for n in
         ("sample_data", "calibrated_sensor", "sensor", "ego_pose", "sample", "scene")}
    sensor = {s["token"]: s["channel"] for s in t["sensor"]}
    channel = {c["token"]: sensor[c["sensor_token"]] for c in t["calibrated_sensor"]}
    pose = {p["token"]: p for p in t["ego_pose"]}
    scene_of = {s["token"]: s["scene_token"] for s in t["sample"]}
    name = {s["token"]: s["name"] for s in t["scene"]}
    tracks = defaultdict(list)
    for sd in t["sample_data"]:
        if sd["is_key_frame"] and channel[sd["calibrated_sensor_token"]] == "LIDAR_TOP":
            tracks[name[scene_of[sd["sample_token"]]]].append((sd["timestamp"], pose[sd["ego_pose_token"]]["translation"]))
    speeds = {}
    for scene, track in tracks.items():
        track.sort()
        speeds[scene] = [math.dist(a[1], b[1]) / ((b[0] - a[0]) / 1e6) for a, b in zip(track, track[1:])]
    return speeds


def test_can_speed_means_equal_python(case):
    root, version, ds = case
    rows = {r["scene_name"]: r for r in can_bus.can_speed(ds).collect().iter_rows(named=True)}
    monitor, pose = _messages(root, "vehicle_monitor"), _messages(root, "pose")
    lidar = _lidar_speeds(root, version)
    assert set(monitor) <= set(rows)
    for scene, messages in monitor.items():
        speeds = [m["vehicle_speed"] / 3.6 for m in messages]
        assert rows[scene]["vehicle_monitor_mean_mps"] == pytest.approx(sum(speeds) / len(speeds), rel=1e-12)
        assert rows[scene]["vehicle_monitor_max_mps"] == pytest.approx(max(speeds), rel=1e-12)
        pose_speeds = [math.sqrt(sum(v * v for v in m["vel"])) for m in pose[scene]]
        assert rows[scene]["pose_mean_mps"] == pytest.approx(sum(pose_speeds) / len(pose_speeds), rel=1e-12)
        ego = lidar[scene]
        assert rows[scene]["ego_pose_mean_mps"] == pytest.approx(sum(ego) / len(ego), rel=1e-9)
        assert rows[scene]["ego_vs_can_mps"] == pytest.approx(sum(ego) / len(ego) - sum(speeds) / len(speeds), abs=1e-9)
        assert abs(rows[scene]["ego_vs_can_mps"]) < 0.5  # the two sources agree on how fast the car went


def test_brake_throttle_equal_python_counts(case):
    root, _, ds = case
    rows = {r["scene_name"]: r for r in can_bus.brake_throttle(ds).collect().iter_rows(named=True)}
    for scene, messages in _messages(root, "vehicle_monitor").items():
        row = rows[scene]
        assert row["messages"] == len(messages)
        assert row["braking_share"] == pytest.approx(sum(m["brake"] > 0 for m in messages) / len(messages))
        assert row["throttle_max"] == max(m["throttle"] for m in messages)
        assert row["brake_mean"] == pytest.approx(sum(m["brake"] for m in messages) / len(messages))


def test_steering_over_time_is_the_messages_relative_to_the_first_sample(case):
    root, version, ds = case
    scenes = json.loads((root / version / "scene.json").read_text())
    samples = {s["token"]: s["timestamp"] for s in json.loads((root / version / "sample.json").read_text())}
    first = {s["name"]: samples[s["first_sample_token"]] for s in scenes}
    steering = can_bus.steering_over_time(ds).collect()
    for scene, messages in _messages(root, "steeranglefeedback").items():
        rows = steering.filter((steering["scene_name"] == scene) & (steering["source"] == "steering_rad"))
        assert rows["value"].to_list() == [m["value"] for m in messages]
        assert rows["time_s"].to_list() == pytest.approx([(m["utime"] - first[scene]) / 1e6 for m in messages])
    for scene, messages in _messages(root, "pose").items():
        rows = steering.filter((steering["scene_name"] == scene) & (steering["source"] == "yaw_rate_radps"))
        assert rows["value"].to_list() == [m["rotation_rate"][2] for m in messages]


def test_a_scene_filter_keeps_only_that_scene(case):
    root, _, ds = case
    scene = sorted(_messages(root, "pose"))[0]
    assert set(can_bus.speed_over_time(ds, scene=scene).collect()["scene_name"]) == {scene}
    assert set(can_bus.can_speed(ds, scene=[scene]).collect()["scene_name"]) == {scene}


@pytest.fixture(scope="module")
def trimmed_start(synth_root, tmp_path_factory):
    """(root, output) of the synthetic set whose first scene's first_sample_token names no sample (a trimmed
    extract's shape), converted with --allow-dangling: that scene has no start time (first_timestamp null)."""
    import os
    import shutil

    base = tmp_path_factory.mktemp("trimmed-start")
    root = base / "data"
    shutil.copytree(synth_root, root, copy_function=os.symlink)
    path = root / SYNTH_VERSION / "scene.json"
    scenes = json.loads(path.read_text())
    scenes[0]["first_sample_token"] = "f" * 32
    path.unlink()
    path.write_text(json.dumps(scenes))
    nuparquet.convert(root, SYNTH_VERSION, base / "out", allow_dangling=True, workers=1)
    return root, scenes[0]["name"], nuparquet.open(base / "out")


def test_can_speed_counts_the_messages_of_a_scene_without_a_start_time(trimmed_start):
    """The mean and max CAN speeds need no time axis: a scene whose first sample is missing keeps every message
    in them (only `speed_over_time`'s time_s is unknown there)."""
    root, scene, ds = trimmed_start
    assert ds.scan("scenes").filter(pl.col("name") == scene).select("first_timestamp").collect().item() is None
    row = can_bus.can_speed(ds, scene=scene).collect().row(0, named=True)
    speeds = [m["vehicle_speed"] / 3.6 for m in _messages(root, "vehicle_monitor")[scene]]
    assert row["scene_name"] == scene and len(speeds) > 1
    assert row["vehicle_monitor_mean_mps"] == pytest.approx(sum(speeds) / len(speeds), rel=1e-12)
    assert row["vehicle_monitor_max_mps"] == pytest.approx(max(speeds), rel=1e-12)
    pose_speeds = [math.sqrt(sum(v * v for v in m["vel"])) for m in _messages(root, "pose")[scene]]
    assert row["pose_mean_mps"] == pytest.approx(sum(pose_speeds) / len(pose_speeds), rel=1e-12)
