"""sample_can_bus against plain-Python computations over the message files: the as-of message and its age, the
interpolated signals (linear; slerp by pyquaternion for quaternions; the gap rule), and the BEVFormer-family
18-value vector against the converters' own loop, reimplemented here as they wrote it."""

from __future__ import annotations

import json

import numpy as np
import polars as pl
import pytest

from conftest import EXTRACT_VERSION, SYNTH_VERSION
from nuparquet.can_bus.align import MAX_INTERPOLATION_GAP_US
from references import bevformer_can_bus


@pytest.fixture(scope="module", params=["extract", "synth", "wild"])
def case(request):
    if request.param == "extract":
        root, version, out = request.getfixturevalue("extract_root"), EXTRACT_VERSION, request.getfixturevalue("extract_out")
    elif request.param == "wild":  # late streams, dropped messages, zoesensors (synth.can_bus, wild)
        root, version, out = request.getfixturevalue("wild_can_root"), SYNTH_VERSION, request.getfixturevalue("wild_can_out")
    else:
        root, version, out = request.getfixturevalue("synth_root"), SYNTH_VERSION, request.getfixturevalue("synth_out")
    samples = json.loads((root / version / "sample.json").read_text())
    scenes = {s["token"]: s["name"] for s in json.loads((root / version / "scene.json").read_text())}
    return root, out, samples, scenes, pl.read_parquet(out / "sample_can_bus")


def _messages(root, scene, message):
    path = root / "can_bus" / f"{scene}_{message}.json"
    return json.loads(path.read_text()) if path.exists() else None


def _message_types(root) -> list[str]:
    """The CAN message types of the dataroot's files (not meta, route)."""
    return sorted({p.stem.split("_", 1)[1] for p in (root / "can_bus").glob("scene-*_*.json")} - {"meta", "route"})


def test_one_row_per_sample(case):
    _, _, samples, _, aligned = case
    assert sorted(aligned["sample_token"]) == sorted(s["token"] for s in samples)


def test_asof_message_and_age_equal_a_plain_search(case):
    root, _, samples, scenes, aligned = case
    rows = {r["sample_token"]: r for r in aligned.iter_rows(named=True)}
    checked_none = checked_some = 0
    for message in _message_types(root):
        for sample in samples:
            messages = _messages(root, scenes[sample["scene_token"]], message)
            row = rows[sample["token"]]
            before = [m for m in messages or [] if m["utime"] <= sample["timestamp"]]
            if not before:
                assert row[message] is None and row[f"{message}_age_us"] is None
                checked_none += 1
                continue
            last = before[-1]
            assert row[message] == last
            assert row[f"{message}_age_us"] == sample["timestamp"] - last["utime"]
            checked_some += 1
    assert checked_none > 0 and checked_some > 0  # both branches reached (messages start after the first sample)


def test_interpolation_equals_plain_python_with_the_gap_rule(case):
    from pyquaternion import Quaternion

    root, _, samples, scenes, aligned = case
    rows = {r["sample_token"]: r for r in aligned.iter_rows(named=True)}
    seen = {"between": 0, "gap": 0, "none": 0}
    for message, fields in (("pose", ("pos", "vel", "orientation")), ("vehicle_monitor", ("vehicle_speed", "steering")),
                            ("steeranglefeedback", ("value",)), ("zoesensors", ("brake_sensor", "throttle_sensor"))):
        if message not in _message_types(root):
            continue
        for sample in samples:
            t = sample["timestamp"]
            messages = _messages(root, scenes[sample["scene_token"]], message) or []
            before = [m for m in messages if m["utime"] <= t]
            after = [m for m in messages if m["utime"] > t]
            got = rows[sample["token"]][f"{message}_interp"]
            if before and before[-1]["utime"] == t:
                expected = {f: before[-1][f] for f in fields}
            elif before and after and after[0]["utime"] - before[-1]["utime"] <= MAX_INTERPOLATION_GAP_US:
                a, b = before[-1], after[0]
                w = (t - a["utime"]) / (b["utime"] - a["utime"])
                expected = {}
                for f in fields:
                    if f == "orientation":
                        expected[f] = list(Quaternion.slerp(Quaternion(a[f]), Quaternion(b[f]), w).q)
                    elif isinstance(a[f], list):
                        expected[f] = [x + w * (y - x) for x, y in zip(a[f], b[f])]
                    else:
                        expected[f] = a[f] + w * (b[f] - a[f])
                seen["between"] += 1
            else:
                assert got is None
                seen["gap" if before and after else "none"] += 1
                continue
            for f in fields:
                np.testing.assert_allclose(got[f], expected[f], rtol=1e-12, atol=1e-12)
    assert seen["between"] > 0 and seen["none"] > 0


def test_real_vehicle_monitor_gap_over_the_limit_is_not_interpolated(extract_root, extract_out):
    """The extract's scene-0523 vehicle_monitor misses one message (a 1.0004 s gap): a sample inside it keeps its
    as-of message but gets no interpolated value."""
    messages = _messages(extract_root, "scene-0523", "vehicle_monitor")
    gaps = [(a["utime"], b["utime"]) for a, b in zip(messages, messages[1:]) if b["utime"] - a["utime"] > MAX_INTERPOLATION_GAP_US]
    assert gaps
    aligned = pl.read_parquet(extract_out / "sample_can_bus").filter(pl.col("scene_name") == "scene-0523")
    inside = aligned.filter(pl.any_horizontal([(pl.col("timestamp") > a) & (pl.col("timestamp") < b) for a, b in gaps]))
    assert inside.height > 0
    assert inside["vehicle_monitor_interp"].is_null().all()
    assert inside["vehicle_monitor"].is_not_null().all()


def test_can_bus_vector_equals_the_converters_loop(case):
    root, _, samples, scenes, aligned = case
    rows = {r["sample_token"]: r for r in aligned.iter_rows(named=True)}
    differs = 0
    for sample in samples:
        poses = _messages(root, scenes[sample["scene_token"]], "pose")  # loaded per sample, as the converter does
        expected = bevformer_can_bus(poses, sample["timestamp"])
        got = rows[sample["token"]]
        assert got["can_bus"] == expected.tolist()
        if poses is None:
            assert got["can_bus_corrected"] is None
            continue
        poses = _messages(root, scenes[sample["scene_token"]], "pose")
        before = [p for p in poses if p["utime"] <= sample["timestamp"]] or poses[:1]
        last = before[-1]
        corrected = [*last["pos"], *last["orientation"], *last["accel"], *last["rotation_rate"], *last["vel"], 0.0, 0.0]
        assert got["can_bus_corrected"] == corrected
        differs += got["can_bus"] != corrected
    assert differs > 0  # the slip is visible in the data: the exact vector is not the corrected one


def test_a_scene_without_can_bus_gets_zeros_and_nulls(synth_root, synth_out):
    scenes_with = {p.name.split("_")[0] for p in (synth_root / "can_bus").glob("*.json")}
    aligned = pl.read_parquet(synth_out / "sample_can_bus")
    without = aligned.filter(~pl.col("scene_name").is_in(sorted(scenes_with)))
    assert without.height > 0
    assert (without["can_bus"].arr.sum() == 0).all() and without["can_bus_corrected"].is_null().all()
    assert without["pose"].is_null().all() and without["pose_age_us"].is_null().all()


def test_a_message_type_with_one_message_in_the_whole_dataset_reaches_only_the_samples_at_or_after_it():
    """One message in all (a short drive's rare message type): a sample before it has none (null, no age), the
    samples at and after it carry it with their age; the other scene's sample has none."""
    from nuparquet.can_bus.align import aligned

    samples = pl.DataFrame({"scene_name": ["scene-0001"] * 3 + ["scene-0002"],
                            "timestamp": [1_000, 2_000, 2_500, 3_000]})
    messages = pl.DataFrame({"scene_name": ["scene-0001"], "utime": [2_000], "value": [7]})
    got = aligned(samples, "rare", messages)
    assert got["rare"].to_list() == [None, {"utime": 2_000, "value": 7}, {"utime": 2_000, "value": 7}, None]
    assert got["rare_age_us"].to_list() == [None, 0, 500, None]


def test_every_float_field_but_utime_is_interpolated_whatever_its_name():
    """The interpolated struct holds the float fields, utime excepted by its exact name: a float field `UTIME`
    (JSON keys are case-sensitive, and the reader takes any field name) is a signal like the others. By hand: at
    1500 halfway between the messages at 1000 and 2000; at 1000 and 2000 the messages' own values; after the last
    message nothing."""
    from nuparquet.can_bus.align import aligned

    samples = pl.DataFrame({"scene_name": ["scene-0001"] * 4, "timestamp": [1_000, 1_500, 2_000, 3_500]})
    messages = pl.DataFrame({"scene_name": ["scene-0001"] * 3, "utime": [1_000, 2_000, 3_000],
                             "speed": [1.0, 3.0, 4.0], "UTIME": [10.0, 20.0, 40.0], "gear": [1, 2, 2]})
    got = aligned(samples, "wild", messages)
    assert got["wild_interp"].to_list() == [{"speed": 1.0, "UTIME": 10.0}, {"speed": 2.0, "UTIME": 15.0},
                                            {"speed": 3.0, "UTIME": 20.0}, None]


def test_rows_are_sorted_by_scene_timestamp_and_sample_token_even_for_samples_at_the_same_time(tmp_path):
    """The documented order (scene_name, timestamp, sample_token): samples of one scene at the same timestamp
    (nothing refuses them) come in token order whatever their order in sample.json. Expectation: Python's sort of
    the input records."""
    from nuparquet.conversion.builder import BuildContext
    from nuparquet.conversion.builders.sample_can_bus import build

    scenes = {"sc-1": "scene-0002", "sc-2": "scene-0001"}
    records = [("t-9", "sc-1", 2_000), ("t-7", "sc-1", 2_000), ("t-8", "sc-1", 1_000), ("t-3", "sc-2", 5_000),
               ("t-2", "sc-2", 5_000), ("t-1", "sc-2", 5_000), ("t-5", "sc-1", 2_000)]
    tables = {"sample": pl.DataFrame({"token": [r[0] for r in records], "scene_token": [r[1] for r in records],
                                      "timestamp": [r[2] for r in records]}),
              "scene": pl.DataFrame({"token": list(scenes), "name": list(scenes.values()), "log_token": ["l", "l"]}),
              "log": pl.DataFrame({"token": ["l"], "location": ["boston-seaport"]})}
    ctx = BuildContext(tmp_path, SYNTH_VERSION, None, None, tables, tmp_path / "out")
    got = build(ctx)
    expected = sorted((scenes[scene], timestamp, token) for token, scene, timestamp in records)
    assert list(got.select("scene_name", "timestamp", "sample_token").iter_rows()) == expected
    assert (got["can_bus"].arr.sum() == 0).all() and got["can_bus_corrected"].is_null().all()  # no CAN bus at all
