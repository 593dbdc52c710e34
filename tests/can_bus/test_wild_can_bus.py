"""CAN bus files as they really are (issue 27, part 6), written by the generator's wild option (`synth.can_bus`):
var_stats objects where ours are null, mixed-case meta keys that are not the file names, a zoesensors stream,
dropped messages (gaps of exactly 1 s and of 1 s + 1 us), every stream starting after the first keyframes. Each
converts exactly, comes back byte for byte from export-json, and aligns to the samples as plain Python (and
BEVFormer's converter loop, as written) computes it. The devkit's view of the same files: tests/parity/
test_can_bus_devkit.py (its "wild" case)."""

from __future__ import annotations

import json

import numpy as np
import polars as pl
import pytest

from conftest import SYNTH_VERSION
from nuparquet.can_bus.align import MAX_INTERPOLATION_GAP_US
from nuparquet.export.json_files import export_json
from references import bevformer_can_bus

SCENES = ("scene-0001", "scene-0002")  # the generator writes no CAN bus for the last scene


def messages(root, scene: str, message: str) -> list[dict]:
    return json.loads((root / "can_bus" / f"{scene}_{message}.json").read_text())


def samples_of(root, scene: str) -> list[dict]:
    token = next(s["token"] for s in json.loads((root / SYNTH_VERSION / "scene.json").read_text()) if s["name"] == scene)
    samples = json.loads((root / SYNTH_VERSION / "sample.json").read_text())
    return sorted((s for s in samples if s["scene_token"] == token), key=lambda s: s["timestamp"])


def gaps(records: list[dict]) -> list[tuple[int, int]]:
    return [(a["utime"], b["utime"]) for a, b in zip(records, records[1:]) if b["utime"] - a["utime"] > 600_000]


def test_the_files_have_the_shapes_of_real_ones(wild_can_root):
    """The generator reaches every case (otherwise the tests below would pass on regular files)."""
    for scene in SCENES:
        meta = json.loads((wild_can_root / "can_bus" / f"{scene}_meta.json").read_text())
        assert list(meta) == ["MS_IMU", "POSE", "SteerAngleFeedback", "VEHICLE_MONITOR", "ZOE_VEH_INFO", "ZoeSensors"]
        assert (wild_can_root / "can_bus" / f"{scene}_zoesensors.json").is_file()
        assert isinstance(meta["ZoeSensors"]["var_stats"], dict) and type(meta["POSE"]["var_stats"]["utime"]["max"]) is int
        samples = samples_of(wild_can_root, scene)
        for message in ("pose", "ms_imu", "steeranglefeedback", "vehicle_monitor", "zoe_veh_info", "zoesensors"):
            records = messages(wild_can_root, scene, message)
            assert records[0]["utime"] > samples[1]["timestamp"], (scene, message)  # two samples before every stream
            assert meta[{"zoesensors": "ZoeSensors", "steeranglefeedback": "SteerAngleFeedback"}.get(
                message, message.upper())]["message_count"] == len(records)
        assert [b - a for a, b in gaps(messages(wild_can_root, scene, "pose"))] == [1_000_000]
        assert [b - a for a, b in gaps(messages(wild_can_root, scene, "steeranglefeedback"))] == [1_000_001]
    vehicle_monitor = [json.loads((wild_can_root / "can_bus" / f"{s}_meta.json").read_text())["VEHICLE_MONITOR"]["var_stats"]
                       for s in SCENES]
    assert isinstance(vehicle_monitor[0], dict) and vehicle_monitor[1] is None  # an object in one scene, null in the other


def test_every_file_converts_and_comes_back_byte_for_byte(wild_can_root, wild_can_out, tmp_path):
    export_json(wild_can_out, tmp_path / "back")
    originals = sorted((wild_can_root / "can_bus").glob("*.json"))
    assert sorted(p.name for p in (tmp_path / "back" / "can_bus").iterdir()) == [p.name for p in originals]
    for path in originals:
        assert (tmp_path / "back" / "can_bus" / path.name).read_bytes() == path.read_bytes(), path.name


def test_zoesensors_is_a_dataset_and_meta_keeps_its_keys_as_spelled(wild_can_root, wild_can_out):
    zoesensors = pl.read_parquet(wild_can_out / "can_bus" / "zoesensors")
    assert zoesensors.columns == ["scene_name", "utime", "brake_sensor", "steering_sensor", "throttle_sensor"]
    meta = pl.read_parquet(wild_can_out / "can_bus" / "meta")
    for scene in SCENES:
        source = json.loads((wild_can_root / "can_bus" / f"{scene}_meta.json").read_text())
        rows = meta.filter(pl.col("scene_name") == scene)
        assert rows["message"].to_list() == list(source)  # ZoeSensors, SteerAngleFeedback: as spelled
        for row in rows.iter_rows(named=True):
            stats = source[row["message"]]["var_stats"]
            assert (None if row["var_stats"] is None else json.loads(row["var_stats"])) == stats
            # the devkit's link from a meta key to a message file: the key lower-cased
            dataset = pl.read_parquet(wild_can_out / "can_bus" / row["message"].lower())
            assert dataset.filter(pl.col("scene_name") == scene).height == row["message_count"]


def test_meta_counts_name_the_converted_messages_in_the_real_extract_too(extract_root, extract_out):
    meta = pl.read_parquet(extract_out / "can_bus" / "meta")
    checked = 0
    for row in meta.iter_rows(named=True):
        if (extract_root / "can_bus" / f"{row['scene_name']}_{row['message'].lower()}.json").is_file():
            rows = pl.read_parquet(extract_out / "can_bus" / row["message"].lower())
            assert rows.filter(pl.col("scene_name") == row["scene_name"]).height == row["message_count"]
            checked += 1
    assert checked == 8  # pose, ms_imu, steeranglefeedback, vehicle_monitor of two scenes (zoe* files are absent)


@pytest.mark.parametrize("message, field, interpolated", [("pose", "pos", True), ("steeranglefeedback", "value", False)])
def test_a_dropped_message_gap_is_interpolated_up_to_exactly_one_second(wild_can_root, wild_can_out, message, field,
                                                                        interpolated):
    aligned = pl.read_parquet(wild_can_out / "sample_can_bus")
    inside = 0
    for scene in SCENES:
        (start, end), = gaps(messages(wild_can_root, scene, message))
        assert (end - start <= MAX_INTERPOLATION_GAP_US) is interpolated
        records = {m["utime"]: m for m in messages(wild_can_root, scene, message)}
        for row in aligned.filter((pl.col("scene_name") == scene) & (pl.col("timestamp") > start)
                                  & (pl.col("timestamp") < end)).iter_rows(named=True):
            inside += 1
            assert row[message] == records[start]  # the as-of message is the one before the gap, either way
            if not interpolated:
                assert row[f"{message}_interp"] is None
                continue
            w = (row["timestamp"] - start) / (end - start)
            a, b = np.array(records[start][field]), np.array(records[end][field])
            np.testing.assert_allclose(row[f"{message}_interp"][field], a + w * (b - a), rtol=1e-12, atol=1e-9)
    assert inside >= 2  # a sample falls inside the gap in each scene


def test_samples_before_every_message_get_the_first_pose_in_the_bevformer_vector(wild_can_root, wild_can_out):
    aligned = {r["sample_token"]: r for r in pl.read_parquet(wild_can_out / "sample_can_bus").iter_rows(named=True)}
    early = 0
    for scene in SCENES:
        first = messages(wild_can_root, scene, "pose")[0]
        for sample in samples_of(wild_can_root, scene):
            row = aligned[sample["token"]]
            expected = bevformer_can_bus(messages(wild_can_root, scene, "pose"), sample["timestamp"])
            assert row["can_bus"] == expected.tolist()
            if sample["timestamp"] < first["utime"]:
                early += 1
                assert row["pose"] is None and row["pose_age_us"] is None and row["pose_interp"] is None
                assert row["can_bus"] == [*first["pos"], *first["orientation"], *first["accel"], *first["rotation_rate"],
                                          *first["vel"], 0.0, 0.0]
                assert row["can_bus_corrected"] == row["can_bus"]  # one message for every value: they agree
    assert early == 2 * len(SCENES)  # the first two samples of each scene precede every message
