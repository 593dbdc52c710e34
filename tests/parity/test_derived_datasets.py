"""The denormalised datasets against the devkit (real extract and synthetic data) and plain-Python
computations from the JSON."""

from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import polars as pl
import pyarrow.parquet as pq
import pytest

from conftest import EXTRACT_VERSION, IRREGULAR_VERSION, SYNTH_VERSION


def read(out: Path, dataset: str) -> pl.DataFrame:
    return pl.read_parquet(out / dataset / "*.parquet")


@pytest.fixture(scope="module", params=["extract", "synth", "irregular"])
def case(request):
    """(dataroot, version, converted OUT, devkit NuScenes) for the real extract, a synthetic dataset and the
    irregular synthetic one (gaps of 1-3 s, hills: velocities at the devkit's limits, 3D path lengths)."""
    devkit = request.getfixturevalue("devkit")
    if request.param == "extract":
        root, version, out = request.getfixturevalue("extract_root"), EXTRACT_VERSION, request.getfixturevalue("extract_out")
    elif request.param == "irregular":
        root, out = request.getfixturevalue("irregular_root"), request.getfixturevalue("irregular_out")
        version = IRREGULAR_VERSION
    else:
        root, version, out = request.getfixturevalue("synth_root"), SYNTH_VERSION, request.getfixturevalue("synth_out")
    return root, version, out, devkit.NuScenes(version=version, dataroot=str(root), verbose=False)


def test_velocity_equals_devkit_box_velocity_for_every_annotation(case):
    _, _, out, nusc = case
    annotations = read(out, "annotations").select("token", "velocity")
    ours = dict(zip(annotations["token"].to_list(), annotations["velocity"].to_numpy()))
    assert len(ours) == len(nusc.sample_annotation)
    nan_count = 0
    for record in nusc.sample_annotation:
        expected = nusc.box_velocity(record["token"])
        got = ours[record["token"]]
        if np.isnan(expected).any():
            nan_count += 1
            assert np.isnan(got).all(), record["token"]
        else:
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
    assert 0 < nan_count < len(nusc.sample_annotation)  # both branches exercised


def test_frames_carry_the_devkit_pose_calibration_channel_and_modality(case):
    _, _, out, nusc = case
    frames = read(out, "frames")
    assert frames.height == len(nusc.sample_data)
    rows = {r["token"]: r for r in frames.iter_rows(named=True)}
    for sd in nusc.sample_data:
        row = rows[sd["token"]]
        pose = nusc.get("ego_pose", sd["ego_pose_token"])
        calib = nusc.get("calibrated_sensor", sd["calibrated_sensor_token"])
        assert row["ego_translation"] == pose["translation"] and row["ego_rotation"] == pose["rotation"]
        assert row["sensor_translation"] == calib["translation"] and row["sensor_rotation"] == calib["rotation"]
        # Stored flat, row-major (format 2): the devkit's 3x3 rows one after the other.
        assert (row["camera_intrinsic"] or []) == [x for r in calib["camera_intrinsic"] for x in r]
        assert row["channel"] == sd["channel"] and row["modality"] == sd["sensor_modality"]
        assert row["sample_token"] == sd["sample_token"] and row["timestamp"] == sd["timestamp"]
        scene = nusc.get("scene", nusc.get("sample", sd["sample_token"])["scene_token"])
        assert row["scene_name"] == scene["name"]
        assert row["log_location"] == nusc.get("log", scene["log_token"])["location"]


def test_frame_transforms_equal_the_devkit_transform_matrices(case):
    from nuscenes.utils.geometry_utils import transform_matrix
    from pyquaternion import Quaternion

    _, _, out, nusc = case
    frames = read(out, "frames").filter(pl.col("modality") == "camera").head(40)
    for row in frames.iter_rows(named=True):
        global_from_ego = transform_matrix(row["ego_translation"], Quaternion(row["ego_rotation"]))
        ego_from_sensor = transform_matrix(row["sensor_translation"], Quaternion(row["sensor_rotation"]))
        np.testing.assert_allclose(np.reshape(row["global_from_ego"], (4, 4)), global_from_ego, atol=1e-9)
        np.testing.assert_allclose(np.reshape(row["ego_from_sensor"], (4, 4)), ego_from_sensor, atol=1e-12)
        # A global point 10 m ahead of the camera lands where the devkit chain puts it.
        point = (global_from_ego @ ego_from_sensor @ np.array([0.3, -0.2, 10.0, 1.0]))
        pixel = np.reshape(row["image_from_global"], (4, 4)) @ point
        intrinsic = np.reshape(row["camera_intrinsic"], (3, 3))
        expected = intrinsic @ np.array([0.3, -0.2, 10.0])
        np.testing.assert_allclose(pixel[:2] / pixel[2], expected[:2] / expected[2], atol=1e-6)


def test_per_scene_annotation_counts_equal_the_devkit_full_count(case):
    _, _, out, nusc = case
    expected = {}
    for scene in nusc.scene:
        count, token = 0, scene["first_sample_token"]
        while token:  # every sample, including the last one (list_scenes stops before it)
            sample = nusc.get("sample", token)
            count += len(sample["anns"])
            token = sample["next"]
        expected[scene["name"]] = count
    scenes = read(out, "scenes")
    assert dict(zip(scenes["name"], scenes["num_annotations"])) == expected


def test_annotation_joins_match_the_devkit_records(case):
    _, _, out, nusc = case
    rows = {r["token"]: r for r in read(out, "annotations").iter_rows(named=True)}
    for ann in nusc.sample_annotation[::7]:
        row = rows[ann["token"]]
        assert row["category_name"] == ann["category_name"]
        assert row["attribute_names"] == [nusc.get("attribute", a)["name"] for a in ann["attribute_tokens"]]
        assert row["visibility_level"] == int(ann["visibility_token"])
        assert row["timestamp"] == nusc.get("sample", ann["sample_token"])["timestamp"]
        sample = nusc.get("sample", ann["sample_token"])
        assert row["scene_name"] == nusc.get("scene", sample["scene_token"])["name"]
        lidar = nusc.get("sample_data", sample["data"]["LIDAR_TOP"])
        ego = nusc.get("ego_pose", lidar["ego_pose_token"])["translation"]
        assert row["distance_to_ego_m"] == pytest.approx(math.dist(ann["translation"][:2], ego[:2]), abs=1e-9)
        from pyquaternion import Quaternion

        assert row["yaw"] == pytest.approx(Quaternion(ann["rotation"]).yaw_pitch_roll[0], abs=1e-12)


def test_scenes_and_instances_from_the_json(case):
    root, version, out, _ = case
    tables = {n: json.loads((root / version / f"{n}.json").read_text())
              for n in ("scene", "sample", "sample_annotation", "instance", "log", "sample_data", "ego_pose",
                        "calibrated_sensor", "sensor")}
    sample = {s["token"]: s for s in tables["sample"]}
    scene_of_sample = {s["token"]: s["scene_token"] for s in tables["sample"]}
    scenes = {r["token"]: r for r in read(out, "scenes").iter_rows(named=True)}
    for scene in tables["scene"]:
        row = scenes[scene["token"]]
        first, last = sample[scene["first_sample_token"]]["timestamp"], sample[scene["last_sample_token"]]["timestamp"]
        assert (row["first_timestamp"], row["last_timestamp"]) == (first, last)
        assert row["duration_s"] == pytest.approx((last - first) / 1e6)
        instances = {a["instance_token"] for a in tables["sample_annotation"] if scene_of_sample[a["sample_token"]] == scene["token"]}
        assert row["num_instances"] == len(instances)
    # ego_distance_m: path of the LIDAR_TOP keyframe poses, by plain Python
    sensor_channel = {s["token"]: s["channel"] for s in tables["sensor"]}
    channel_of_calib = {c["token"]: sensor_channel[c["sensor_token"]] for c in tables["calibrated_sensor"]}
    pose = {p["token"]: p["translation"] for p in tables["ego_pose"]}
    path = defaultdict(list)
    for sd in tables["sample_data"]:
        if sd["is_key_frame"] and channel_of_calib[sd["calibrated_sensor_token"]] == "LIDAR_TOP":
            path[scene_of_sample[sd["sample_token"]]].append((sd["timestamp"], pose[sd["ego_pose_token"]]))
    for token, points in path.items():
        points.sort()
        expected = sum(math.dist(a[1], b[1]) for a, b in zip(points, points[1:]))
        assert scenes[token]["ego_distance_m"] == pytest.approx(expected, rel=1e-12)
    # instances: first/last timestamps and track length
    ann = {a["token"]: a for a in tables["sample_annotation"]}
    instances = {r["token"]: r for r in read(out, "instances").iter_rows(named=True)}
    for inst in tables["instance"]:
        row = instances[inst["token"]]
        chain, token = [], inst["first_annotation_token"]
        while token:
            chain.append(ann[token])
            token = ann[token]["next"]
        assert row["nbr_annotations"] == len(chain)
        assert row["first_timestamp"] == sample[chain[0]["sample_token"]]["timestamp"]
        assert row["last_timestamp"] == sample[chain[-1]["sample_token"]]["timestamp"]
        expected = sum(math.dist(a["translation"], b["translation"]) for a, b in zip(chain, chain[1:]))
        assert row["track_length_m"] == pytest.approx(expected, rel=1e-9, abs=1e-12)


def test_real_extract_scenes_have_their_known_split(extract_out):
    scenes = read(extract_out, "scenes")
    assert dict(zip(scenes["name"], scenes["split"])) == {"scene-0523": "val", "scene-0916": "mini_val"}


def test_velocity_is_nan_for_single_annotation_track(synth_out):
    annotations = read(synth_out, "annotations")
    single = annotations.filter((pl.col("prev") == "") & (pl.col("next") == ""))
    assert single.height > 0
    assert np.isnan(single["velocity"].to_numpy()).all()


def test_velocity_is_defined_exactly_where_devkit_box_velocity_answers(devkit):
    """`velocity_defined` (what `--allow-dangling` keeps of the velocity) against the devkit's `box_velocity` run on
    the same small tables: it raises (KeyError) where a prev/next names no annotation or an annotation it reads
    has no sample, and answers elsewhere, a track of one without reading anything, a centred difference without
    reading its own sample."""
    from nuparquet.conversion.builders.annotations import velocity_defined

    samples = {"s1": 0, "s2": 500_000, "s3": 1_000_000}  # "gone" is no sample
    rows = [  # token, sample, prev, next
        ("a1", "s1", "", "a2"), ("a2", "s2", "a1", "a3"), ("a3", "s3", "a2", ""),  # a whole track
        ("b1", "s1", "", "absent"),  # next names no annotation
        ("c1", "gone", "", ""),  # a track of one: NaN, nothing read
        ("d1", "gone", "", "d2"), ("d2", "s2", "d1", ""),  # both ends read d1's absent sample
        ("e1", "s1", "", "e2"), ("e2", "gone", "e1", "e3"), ("e3", "s3", "e2", ""),  # e2 reads e1 and e3 only
    ]

    class Tables:  # what box_velocity reads through `get`: a missing token raises KeyError, as in the devkit
        records = {"sample_annotation": {t: {"token": t, "sample_token": s, "prev": p, "next": n,
                                             "translation": [1.0, 2.0, 0.0]} for t, s, p, n in rows},
                   "sample": {s: {"token": s, "timestamp": ts} for s, ts in samples.items()}}

        def get(self, table, token):
            return self.records[table][token]

    def answers(token) -> bool:
        try:
            devkit.NuScenes.box_velocity(Tables(), token)
        except KeyError:
            return False
        return True

    expected = [answers(t) for t, *_ in rows]
    assert expected == [True, True, True, False, True, False, False, False, True, False]  # every case reached
    ann = pl.DataFrame({"token": [r[0] for r in rows], "timestamp": [samples.get(r[1]) for r in rows],
                        "prev": [r[2] for r in rows], "next": [r[3] for r in rows]},
                       schema_overrides={"timestamp": pl.Int64})
    assert velocity_defined(ann).tolist() == expected


def test_visibility_levels_rank_numeric_ranges_by_their_lower_bound_and_leave_worded_levels_without_one():
    """nuScenes' levels ("v0-40" .. "v80-100", given in any order, with hash tokens) rank 1..4 by their lower bound
    (the devkit's tokens "1".."4" are that rank); bounds may be decimals, lack the "v", carry spaces or a "%"; a
    table with any worded level (T4's "full", "most", ...) ranks none. Expectations by hand."""
    from nuparquet.conversion.builders.annotations import visibility_levels

    def levels(names):
        table = pl.DataFrame({"token": [f"h{i}" for i in range(len(names))], "level": names,
                              "description": [f"about {n}" for n in names]})
        out = visibility_levels(table)
        assert out["visibility_token"].to_list() == table["token"].to_list()
        assert out["visibility_name"].cast(pl.String).to_list() == names
        assert out["visibility_description"].cast(pl.String).to_list() == [f"about {n}" for n in names]
        assert out.schema["visibility_level"] == pl.Int8
        return out["visibility_level"].to_list()

    assert levels(["v60-80", "v0-40", "v80-100", "v40-60"]) == [3, 1, 4, 2]
    assert levels(["12.5 - 40%", "0-12.5%", "v40-100"]) == [2, 1, 3]
    assert levels(["full", "most", "partial", "none"]) == [None] * 4
    assert levels(["v0-40", "most"]) == [None, None]  # one worded level: no ranking at all


@pytest.mark.parametrize("dataset", ["frames", "annotations"])
def test_one_scene_filter_prunes_row_groups(extract_out, dataset):
    """Row groups follow scene boundaries, so statistics exclude every other scene's groups."""
    file = next((extract_out / dataset).glob("*.parquet"))
    metadata = pq.ParquetFile(file).metadata
    column = metadata.schema.names.index("scene_name")
    scene = "scene-0916"
    may_match = [g for g in range(metadata.num_row_groups)
                 if metadata.row_group(g).column(column).statistics.min <= scene <= metadata.row_group(g).column(column).statistics.max]
    assert metadata.num_row_groups >= 2 and 0 < len(may_match) < metadata.num_row_groups
    # And pyarrow's dataset scanner, given the filter, reads only those row groups' rows.
    import pyarrow.dataset as ds

    fragments = list(ds.dataset(file).get_fragments(filter=ds.field("scene_name") == scene))
    kept = [rg.id for f in fragments for piece in f.split_by_row_group(ds.field("scene_name") == scene)
            for rg in piece.row_groups]
    assert kept == may_match
    rows_read = sum(metadata.row_group(g).num_rows for g in kept)
    assert rows_read == pl.scan_parquet(file).filter(pl.col("scene_name") == scene).select(pl.len()).collect().item()


def test_distance_to_ego_is_null_without_a_reference_keyframe(synth_root, tmp_path):
    """The schema promises null (not NaN) when a sample has no LIDAR_TOP keyframe."""
    import shutil

    from nuparquet.conversion import convert

    shutil.copytree(synth_root / SYNTH_VERSION, tmp_path / "data" / SYNTH_VERSION)
    path = tmp_path / "data" / SYNTH_VERSION / "sensor.json"
    sensors = json.loads(path.read_text())
    for s in sensors:
        if s["modality"] == "lidar":
            s["channel"], s["modality"] = "LIDAR_ELSEWHERE", "other"  # no lidar channel left at all
    path.write_text(json.dumps(sensors))
    convert(tmp_path / "data", SYNTH_VERSION, tmp_path / "out")
    distance = read(tmp_path / "out", "annotations")["distance_to_ego_m"]
    assert distance.null_count() == len(distance) and not distance.is_nan().any()


def test_rows_are_stored_in_the_documented_order(case):
    """Row order is what lets a scene filter skip row groups: instances by (scene, first timestamp, token),
    annotations by (scene, timestamp, instance, token), frames by (scene, channel, timestamp, token), scenes by
    (name, token). Checked against Python sorting of the rows as stored."""
    _, _, out, _ = case
    for dataset, keys in (("instances", ("scene_name", "first_timestamp", "token")),
                          ("frames", ("scene_name", "channel", "timestamp", "token")),
                          ("annotations", ("scene_name", "timestamp", "instance_token", "token")),
                          ("scenes", ("name", "token"))):
        files = sorted((out / dataset).glob("*.parquet"))
        rows = [tuple(r) for f in files for r in pl.read_parquet(f).select(keys).iter_rows()]
        assert rows == sorted(rows), dataset


def test_a_track_of_one_annotation_has_length_zero(case):
    """An instance annotated once has no path: track_length_m is 0.0 (not null, not a step of its own)."""
    _, version, out, _ = case
    instances = pl.read_parquet(out / "instances")
    single = instances.filter(pl.col("nbr_annotations") == 1)
    if version == IRREGULAR_VERSION:
        assert single.height > 0  # the fixture's single-annotation tracks
    assert single["track_length_m"].to_list() == [0.0] * single.height


def test_track_and_ego_path_lengths_follow_time_not_the_order_of_the_json(irregular_root, irregular_out, tmp_path):
    """The JSON order of sample_annotation and sample_data is arbitrary: shuffled, the same path lengths come out
    (summed in time order), equal to walking each instance's chain of annotations."""
    import random
    import shutil

    from nuparquet.conversion import convert

    root = tmp_path / "shuffled"
    shutil.copytree(irregular_root / IRREGULAR_VERSION, root / IRREGULAR_VERSION)
    for table in ("sample_annotation", "sample_data"):
        path = root / IRREGULAR_VERSION / f"{table}.json"
        records = json.loads(path.read_text())
        random.Random(3).shuffle(records)
        path.write_text(json.dumps(records))
    out = tmp_path / "out"
    convert(root, IRREGULAR_VERSION, out)
    ann = {a["token"]: a for a in json.loads((root / IRREGULAR_VERSION / "sample_annotation.json").read_text())}
    instances = json.loads((root / IRREGULAR_VERSION / "instance.json").read_text())
    lengths = dict(read(out, "instances").select("token", "track_length_m").iter_rows())
    moving = 0
    for inst in instances:
        chain, token = [], inst["first_annotation_token"]
        while token:
            chain.append(ann[token]["translation"])
            token = ann[token]["next"]
        expected = sum(math.dist(a, b) for a, b in zip(chain, chain[1:]))
        moving += expected > 0
        assert lengths[inst["token"]] == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert moving > 0
    shuffled = read(out, "scenes").sort("token")["ego_distance_m"].to_list()
    in_order = read(irregular_out, "scenes").sort("token")["ego_distance_m"].to_list()
    assert shuffled == pytest.approx(in_order, rel=1e-12) and all(d > 0 for d in in_order)
