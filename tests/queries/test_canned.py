"""Every canned query in nuparquet.queries against plain Python over the source JSON (real extract and synthetic
data); the comparisons with the devkit's printed listings are in tests/parity/test_listings_devkit.py."""

from __future__ import annotations

import datetime as dt
import json
import math
import statistics
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from polars.testing import assert_frame_equal

import nuparquet
from conftest import EXTRACT_VERSION, SYNTH_VERSION
from nuparquet import queries

CORE = ("attribute", "calibrated_sensor", "category", "ego_pose", "instance", "log", "sample", "sample_annotation",
        "sample_data", "scene", "sensor")


class JsonSource:
    """The source JSON tables of one dataroot, and the plain-Python joins the reference computations need."""

    def __init__(self, root: Path, version: str):
        self.t = {name: json.loads((Path(root) / version / f"{name}.json").read_text()) for name in CORE}
        self.by_token = {name: {r["token"]: r for r in records} for name, records in self.t.items()}
        cs, sensor = self.by_token["calibrated_sensor"], self.by_token["sensor"]
        self.channel = {sd["token"]: sensor[cs[sd["calibrated_sensor_token"]]["sensor_token"]]
                        for sd in self.t["sample_data"]}
        sample, scene = self.by_token["sample"], self.by_token["scene"]
        self.scene_of_sample = {s["token"]: scene[s["scene_token"]] for s in self.t["sample"]}
        category = self.by_token["category"]
        self.category_of_instance = {i["token"]: category[i["category_token"]]["name"] for i in self.t["instance"]}
        lidar_pose = {}
        for sd in self.t["sample_data"]:
            if sd["is_key_frame"] and self.channel[sd["token"]]["channel"] == "LIDAR_TOP":
                lidar_pose[sd["sample_token"]] = (sd["timestamp"], self.by_token["ego_pose"][sd["ego_pose_token"]])
        self.lidar_pose = lidar_pose
        self.annotations = []
        for a in self.t["sample_annotation"]:
            ego = lidar_pose.get(a["sample_token"])
            self.annotations.append({
                **a, "category": self.category_of_instance[a["instance_token"]],
                "scene_name": self.scene_of_sample[a["sample_token"]]["name"],
                "timestamp": sample[a["sample_token"]]["timestamp"],
                "attribute_names": [self.by_token["attribute"][t]["name"] for t in a["attribute_tokens"]],
                "distance": None if ego is None else math.hypot(a["translation"][0] - ego[1]["translation"][0],
                                                                a["translation"][1] - ego[1]["translation"][1]),
            })

    def scene_samples(self, scene: dict) -> list[dict]:
        """The samples of `scene` in chain order."""
        out, token = [], scene["first_sample_token"]
        while token:
            out.append(self.by_token["sample"][token])
            token = out[-1]["next"]
        return out


@pytest.fixture(scope="module", params=["extract", "synth"])
def case(request):
    """(JsonSource, nuparquet Dataset) for the real extract and for a synthetic dataset."""
    if request.param == "extract":
        root, version, out = request.getfixturevalue("extract_root"), EXTRACT_VERSION, request.getfixturevalue("extract_out")
    else:
        root, version, out = request.getfixturevalue("synth_root"), SYNTH_VERSION, request.getfixturevalue("synth_out")
    return JsonSource(root, version), nuparquet.open(out)


def rows_by(df: pl.DataFrame, *keys: str) -> dict:
    return {tuple(r[k] for k in keys) if len(keys) > 1 else r[keys[0]]: r for r in df.iter_rows(named=True)}


# --- plain Python from the JSON, real extract and synthetic --------------------------------------------------------

def test_class_distribution_equals_python_statistics(case):
    source, ds = case
    for by_scene in (False, True):
        ours = queries.class_distribution(ds, by_scene=by_scene).collect()
        groups = defaultdict(list)
        for a in source.annotations:
            groups[((a["scene_name"],) if by_scene else ()) + (a["category"],)].append(a)
        keys = ["scene_name", "category_name"] if by_scene else ["category_name"]
        got = rows_by(ours, *keys)
        assert set(got) == {k if by_scene else k[0] for k in groups}
        assert ours.select(keys).rows() == sorted(ours.select(keys).rows())
        for key, members in groups.items():
            row = got[key if by_scene else key[0]]
            assert row["num_annotations"] == len(members)
            assert row["num_instances"] == len({a["instance_token"] for a in members})
            width = [a["size"][0] for a in members]
            aspect = [a["size"][1] / a["size"][0] for a in members]
            assert row["width_mean"] == pytest.approx(statistics.fmean(width), rel=1e-12)
            assert row["width_std"] == pytest.approx(statistics.pstdev(width), rel=1e-9, abs=1e-12)
            assert row["lw_aspect_mean"] == pytest.approx(statistics.fmean(aspect), rel=1e-12)
            assert row["lw_aspect_std"] == pytest.approx(statistics.pstdev(aspect), rel=1e-9, abs=1e-12)


def test_attribute_counts_equal_python_counts(case):
    source, ds = case
    expected = Counter(name for a in source.annotations for name in a["attribute_names"])
    ours = queries.attribute_counts(ds).collect()
    assert dict(ours.rows()) == expected and ours["attribute_name"].to_list() == sorted(expected)
    by_category = Counter((a["category"], n) for a in source.annotations for n in a["attribute_names"])
    ours = queries.attribute_counts(ds, by_category=True).collect()
    assert {(c, n): k for c, n, k in ours.rows()} == by_category


def test_visibility_by_category_equals_python_counts(case):
    source, ds = case
    expected = Counter((a["category"], int(a["visibility_token"])) for a in source.annotations)
    totals = Counter(a["category"] for a in source.annotations)
    ours = queries.visibility_by_category(ds).collect()
    assert {(c, v): n for c, v, n, _ in ours.rows()} == expected
    for category, level, count, share in ours.rows():
        assert share == pytest.approx(count / totals[category])


def test_points_per_box_equals_numpy_percentiles(case):
    source, ds = case
    ours = rows_by(queries.points_per_box(ds).collect(), "category_name")
    groups = defaultdict(list)
    for a in source.annotations:
        groups[a["category"]].append((a["num_lidar_pts"], a["num_radar_pts"]))
    assert set(ours) == set(groups)
    for category, values in groups.items():
        values = np.array(values)
        row = ours[category]
        assert row["num_boxes"] == len(values)
        for i, sensor in enumerate(("lidar", "radar")):
            column = values[:, i]
            assert row[f"{sensor}_mean"] == pytest.approx(column.mean())
            assert (row[f"{sensor}_min"], row[f"{sensor}_max"]) == (column.min(), column.max())
            for q in (5, 25, 50, 75, 95):
                assert row[f"{sensor}_p{q:02d}"] == pytest.approx(np.percentile(column, q))
            assert row[f"{sensor}_zero_share"] == pytest.approx(np.mean(column == 0))


def test_distance_histogram_equals_python_binning_of_lidar_keyframe_distances(case):
    source, ds = case
    for width in (10.0, 7.5):
        expected = Counter((a["category"], math.floor(a["distance"] / width) * width)
                           for a in source.annotations if a["distance"] is not None)
        ours = queries.distance_histogram(ds, bin_width_m=width).collect()
        assert {(c, start): n for c, start, _, n in ours.rows()} == expected
        assert (ours["bin_end_m"] - ours["bin_start_m"] == width).all()


def test_track_stats_equal_python_walk_of_each_instance(case):
    source, ds = case
    annotation, sample = source.by_token["sample_annotation"], source.by_token["sample"]
    per_category = defaultdict(list)
    for instance in source.t["instance"]:
        chain, token = [], instance["first_annotation_token"]
        while token:
            chain.append(annotation[token])
            token = chain[-1]["next"]
        duration_s = (sample[chain[-1]["sample_token"]]["timestamp"] - sample[chain[0]["sample_token"]]["timestamp"]) / 1e6
        length_m = sum(math.dist(a["translation"], b["translation"]) for a, b in zip(chain, chain[1:]))
        per_category[source.category_of_instance[instance["token"]]].append(
            (instance["nbr_annotations"], duration_s, length_m))
    ours = rows_by(queries.track_stats(ds).collect(), "category_name")
    assert set(ours) == set(per_category)
    assert list(ours) == sorted(per_category)  # one row per category, by name
    for category, tracks in per_category.items():
        row = ours[category]
        assert row["num_tracks"] == len(tracks)
        for i, name in enumerate(("annotations", "duration_s", "length_m")):
            values = [t[i] for t in tracks]
            assert row[f"{name}_mean"] == pytest.approx(statistics.fmean(values), abs=1e-9)
            assert row[f"{name}_median"] == pytest.approx(statistics.median(values), abs=1e-9)
            assert row[f"{name}_max"] == pytest.approx(max(values), abs=1e-9)


def test_track_stats_by_scene_count_each_instance_in_the_scene_of_its_first_annotation_sorted(case):
    source, ds = case
    annotation = source.by_token["sample_annotation"]
    expected = Counter((source.scene_of_sample[annotation[i["first_annotation_token"]]["sample_token"]]["name"],
                        source.category_of_instance[i["token"]]) for i in source.t["instance"])
    ours = queries.track_stats(ds, by_scene=True).collect()
    assert ours.select("scene_name", "category_name").rows() == sorted(expected)  # by scene, then category
    assert dict(zip(zip(ours["scene_name"], ours["category_name"]), ours["num_tracks"])) == expected
    assert len({scene for scene, _ in expected}) > 1


def test_scene_summary_equals_python_walk_of_each_scene(case):
    source, ds = case
    ours = queries.scene_summary(ds).collect()
    anns_per_sample = Counter(a["sample_token"] for a in source.annotations)
    expected = []
    for scene in source.t["scene"]:
        samples = source.scene_samples(scene)
        log = source.by_token["log"][scene["log_token"]]
        expected.append({
            "name": scene["name"], "description": scene["description"],
            "start_utc": dt.datetime.fromtimestamp(samples[0]["timestamp"] / 1e6, dt.timezone.utc),
            "date_captured": log["date_captured"], "duration_s": (samples[-1]["timestamp"] - samples[0]["timestamp"]) / 1e6,
            "log_location": log["location"], "vehicle": log["vehicle"], "nbr_samples": len(samples),
            "num_annotations": sum(anns_per_sample[s["token"]] for s in samples),
            "num_annotations_list_scenes": sum(anns_per_sample[s["token"]] for s in samples[:-1]),
            "num_instances": len({a["instance_token"] for a in source.annotations if a["scene_name"] == scene["name"]}),
        })
    expected.sort(key=lambda r: r["start_utc"])
    assert ours["name"].to_list() == [r["name"] for r in expected]
    for row, want in zip(ours.iter_rows(named=True), expected):
        for key, value in want.items():
            if key == "start_utc":
                assert abs((row[key] - value).total_seconds()) < 1e-5
            elif isinstance(value, float):
                assert row[key] == pytest.approx(value), key
            else:
                assert row[key] == value, key


def _python_ego_motion(source: JsonSource) -> dict[str, list[tuple]]:
    """scene -> [(timestamp, speed, accel, (x, y, z))] from the LIDAR_TOP keyframe poses, in sample order."""
    out = {}
    for scene in source.t["scene"]:
        poses = [source.lidar_pose[s["token"]] for s in source.scene_samples(scene) if s["token"] in source.lidar_pose]
        rows, speeds = [], []
        for i, (t, pose) in enumerate(poses):
            speed = accel = None
            if i:
                dt_s = (t - poses[i - 1][0]) / 1e6
                speed = math.dist(pose["translation"], poses[i - 1][1]["translation"]) / dt_s
                if i >= 2:
                    accel = (speed - speeds[-1]) / ((t - poses[i - 2][0]) / 2e6)
            speeds.append(speed)
            rows.append((t, speed, accel, tuple(pose["translation"])))
        out[scene["name"]] = rows
    return out


def test_ego_motion_equals_python_finite_differences_of_lidar_keyframe_poses(case):
    source, ds = case
    expected = _python_ego_motion(source)
    ours = queries.ego_motion(ds).collect()
    for scene_name, rows in expected.items():
        got = ours.filter(pl.col("scene_name") == scene_name)
        assert got["timestamp"].to_list() == [r[0] for r in rows]
        assert list(zip(got["x_m"], got["y_m"], got["z_m"])) == [r[3] for r in rows]  # the ego position, z too
        for (_, speed, accel, _), got_speed, got_accel in zip(rows, got["speed_mps"], got["accel_mps2"]):
            assert (got_speed is None) == (speed is None) and (got_accel is None) == (accel is None)
            if speed is not None:
                assert got_speed == pytest.approx(speed, rel=1e-9)
            if accel is not None:
                assert got_accel == pytest.approx(accel, rel=1e-9, abs=1e-9)
    summary = rows_by(queries.ego_speed_summary(ds).collect(), "scene_name")
    for scene_name, rows in expected.items():
        speeds = [r[1] for r in rows if r[1] is not None]
        assert summary[scene_name]["keyframes"] == len(rows)
        assert summary[scene_name]["max_speed_mps"] == pytest.approx(max(speeds))
        duration_s = (rows[-1][0] - rows[0][0]) / 1e6
        distance = sum(s * (b[0] - a[0]) / 1e6 for s, a, b in zip(speeds, rows, rows[1:]))
        assert summary[scene_name]["mean_speed_mps"] == pytest.approx(distance / duration_s)


def test_ego_distance_of_summary_equals_scenes_dataset(case):
    _, ds = case
    scenes = rows_by(queries.scene_summary(ds).collect(), "name")
    for row in queries.ego_speed_summary(ds).collect().iter_rows(named=True):
        assert row["distance_m"] == pytest.approx(scenes[row["scene_name"]]["ego_distance_m"])


def test_channel_rates_equal_python_counts_and_timestamp_spans(case):
    source, ds = case
    per = defaultdict(list)
    for sd in source.t["sample_data"]:
        per[(source.scene_of_sample[sd["sample_token"]]["name"], source.channel[sd["token"]]["channel"])].append(sd)
    ours_by_scene = rows_by(queries.channel_rates(ds, by_scene=True).collect(), "scene_name", "channel")
    assert set(ours_by_scene) == set(per)
    totals = defaultdict(lambda: [0, 0, 0, 0, 0, 0])  # frames, keyframes, frame intervals, span, key intervals, key span
    for key, frames in per.items():
        stamps = sorted(sd["timestamp"] for sd in frames)
        key_stamps = sorted(sd["timestamp"] for sd in frames if sd["is_key_frame"])
        row = ours_by_scene[key]
        assert (row["num_frames"], row["num_keyframes"], row["num_sweeps"]) == (
            len(stamps), len(key_stamps), len(stamps) - len(key_stamps))
        assert row["frame_hz"] == pytest.approx((len(stamps) - 1) / ((stamps[-1] - stamps[0]) / 1e6))
        if len(key_stamps) > 1:
            assert row["keyframe_hz"] == pytest.approx((len(key_stamps) - 1) / ((key_stamps[-1] - key_stamps[0]) / 1e6))
        t = totals[key[1]]
        t[0] += len(stamps); t[1] += len(key_stamps); t[2] += len(stamps) - 1; t[3] += stamps[-1] - stamps[0]
        t[4] += max(len(key_stamps) - 1, 0); t[5] += (key_stamps[-1] - key_stamps[0]) if key_stamps else 0
    ours = rows_by(queries.channel_rates(ds).collect(), "channel")
    assert set(ours) == set(totals)
    for channel, (frames, keyframes, intervals, span, key_intervals, key_span) in totals.items():
        row = ours[channel]
        assert (row["num_frames"], row["num_keyframes"]) == (frames, keyframes)
        assert row["frame_hz"] == pytest.approx(intervals * 1e6 / span)
        assert row["keyframe_hz"] == pytest.approx(key_intervals * 1e6 / key_span)


# --- API shape --------------------------------------------------------------------------------------------------

def test_queries_accept_lazyframes_or_a_dataset_and_agree(extract_out):
    ds = nuparquet.open(extract_out)
    pairs = [
        (queries.class_distribution(ds), queries.class_distribution(ds.scan("annotations"))),
        (queries.track_stats(ds), queries.track_stats(ds.scan("instances"))),
        (queries.channel_rates(ds), queries.channel_rates(ds.scan("frames"))),
        (queries.scene_summary(ds), queries.scene_summary(ds.scan("scenes"), ds.scan("annotations"))),
    ]
    for from_dataset, from_frames in pairs:
        assert isinstance(from_dataset, pl.LazyFrame) and isinstance(from_frames, pl.LazyFrame)
        assert_frame_equal(from_dataset.collect(), from_frames.collect(), rel_tol=1e-12)


def test_scene_argument_restricts_every_query_to_that_scene(extract_out):
    ds = nuparquet.open(extract_out)
    scene = ds.scan("scenes").select("name").collect()["name"][0]
    from nuparquet.queries.sections import BY_NAME

    # the real extract has no map expansion, and lidarseg needs --sensors lidar: only sections it holds
    held = [name for name in queries.SECTIONS + queries.EXTRA_SECTIONS if set(BY_NAME[name].requires) <= set(ds.datasets)]
    one = queries.summary(ds, scene=scene, sections=held)
    results = dict(zip(one, pl.collect_all(list(one.values()))))
    assert results["scenes"]["name"].to_list() == [scene]
    for name in ("ego_speed", "class_distribution_by_scene", "channel_rates_by_scene", "ego_motion"):
        assert set(results[name]["scene_name"]) == {scene}
    total = ds.scan("annotations").filter(pl.col("scene_name") == scene).select(pl.len()).collect().item()
    assert results["class_distribution"]["num_annotations"].sum() == total
    by_scene = queries.class_distribution(ds, by_scene=True).collect().filter(pl.col("scene_name") == scene)
    assert_frame_equal(results["class_distribution"], by_scene.drop("scene_name"), check_exact=False, rel_tol=1e-12)


def test_summary_rejects_unknown_sections(extract_out):
    with pytest.raises(ValueError, match="unknown section"):
        queries.summary(nuparquet.open(extract_out), sections=["nope"])


def test_a_list_of_scenes_restricts_every_query_to_those_scenes(case):
    """The list form of `scene` (as `stats --scene A --scene B`): counts equal plain Python over those scenes
    only, and every per-scene section holds exactly them."""
    source, ds = case
    names = sorted(s["name"] for s in source.t["scene"])
    chosen = [names[-1], names[0]]  # unsorted, first and last: not a prefix of the sorted names
    from nuparquet.queries.sections import BY_NAME

    held = [name for name in queries.SECTIONS + queries.EXTRA_SECTIONS  # sections whose datasets this output holds
            if set(BY_NAME[name].requires) <= set(ds.datasets)]
    results = queries.summary(ds, scene=chosen, sections=held)
    results = dict(zip(results, pl.collect_all(list(results.values()))))
    assert sorted(results["scenes"]["name"].to_list()) == sorted(chosen)
    for name in ("ego_speed", "class_distribution_by_scene", "channel_rates_by_scene", "ego_motion"):
        assert set(results[name]["scene_name"]) == set(chosen), name
    members = [a for a in source.annotations if a["scene_name"] in chosen]
    assert results["class_distribution"]["num_annotations"].sum() == len(members)
    expected = Counter(a["category"] for a in members)
    assert dict(zip(results["class_distribution"]["category_name"], results["class_distribution"]["num_annotations"])) \
        == dict(expected)
    frames = Counter(source.channel[sd["token"]]["channel"] for sd in source.t["sample_data"]
                     if source.scene_of_sample[sd["sample_token"]]["name"] in chosen)
    assert dict(zip(results["channel_rates"]["channel"].cast(pl.String), results["channel_rates"]["num_frames"])) \
        == dict(frames)
    one = queries.summary(ds, scene=[names[0]], sections=["class_distribution"])["class_distribution"].collect()
    assert one["num_annotations"].sum() == sum(a["scene_name"] == names[0] for a in source.annotations)
