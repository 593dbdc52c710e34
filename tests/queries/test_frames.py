"""Ego motion follows the reference lidar of the data, not a fixed channel name."""

from __future__ import annotations

import json
import shutil

import polars as pl
import pytest

import nuparquet
from nuparquet.queries import ego_motion, ego_speed_summary


def _frames(channels: list[str]) -> pl.LazyFrame:
    """Two keyframes per lidar channel in one scene; channel i moves (i + 1) * 10 m between them in 1 s; one
    camera that moves 1000 m (must never count)."""
    rows = []
    for i, channel in enumerate(channels + ["CAM_X"]):
        step_m = 1000.0 if channel == "CAM_X" else (i + 1) * 10.0
        for k in range(2):
            rows.append({"scene_name": "s", "channel": channel, "modality": "camera" if channel == "CAM_X" else "lidar",
                         "is_key_frame": True, "timestamp": 1_000_000 * k, "ego_translation": [k * step_m, 0.0, 0.0]})
    return pl.DataFrame(rows, schema_overrides={"ego_translation": pl.Array(pl.Float64, 3)}).lazy()


def test_ego_motion_uses_the_first_lidar_by_name_when_there_is_no_lidar_top():
    motion = ego_motion(_frames(["LIDAR_B", "LIDAR_A"])).collect()
    assert motion.height == 2 and motion["speed_mps"][1] == pytest.approx(20.0)  # LIDAR_A: index 1, 20 m/s


def test_ego_motion_prefers_lidar_top():
    summary = ego_speed_summary(_frames(["LIDAR_A", "LIDAR_TOP"])).collect()
    assert summary["distance_m"][0] == pytest.approx(20.0) and summary["keyframes"][0] == 2


def test_ego_motion_of_a_dataset_uses_the_reference_lidar_it_records(synth_out, tmp_path):
    copy = tmp_path / "out"
    shutil.copytree(synth_out, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["channels"] = {"reference_lidar": "RADAR_FRONT", "cameras": [], "camera_layout": [], "lidars": [],
                            "radars": ["RADAR_FRONT"]}
    (copy / "manifest.json").write_text(json.dumps(manifest))
    ds = nuparquet.open(copy)
    keyframes = ds.scan("frames").filter(pl.col("channel").cast(pl.String) == "RADAR_FRONT",
                                         pl.col("is_key_frame")).select(pl.len()).collect().item()
    motion = ego_motion(ds).collect()
    assert motion.height == keyframes
    expected = ego_motion(ds.scan("frames"), channel="RADAR_FRONT").collect()
    assert motion.equals(expected)
