"""Devkit parity of the listings: Every canned query in nuparquet.queries against an independent computation: the devkit's printed
list_categories / list_attributes / list_scenes on the real extract, and plain Python over the source JSON
(real extract and synthetic data)."""

from __future__ import annotations

import contextlib
import datetime as dt
import io
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


@pytest.fixture(scope="module")
def nusc(devkit, extract_root):
    return devkit.NuScenes(version=EXTRACT_VERSION, dataroot=str(extract_root), verbose=False)


def printed(function) -> list[str]:
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        function()
    return buffer.getvalue().splitlines()


def rows_by(df: pl.DataFrame, *keys: str) -> dict:
    return {tuple(r[k] for k in keys) if len(keys) > 1 else r[keys[0]]: r for r in df.iter_rows(named=True)}


# --- devkit, real extract ----------------------------------------------------------------------------------------

def test_class_distribution_prints_exactly_what_devkit_list_categories_prints(nusc, extract_out):
    from nuscenes.nuscenes import NuScenesExplorer

    ours = queries.class_distribution(nuparquet.open(extract_out)).collect()
    lines = [f"Category stats for split {nusc.version}:"] + [
        "{:27} n={:5}, width={:5.2f}\u00B1{:.2f}, len={:5.2f}\u00B1{:.2f}, height={:5.2f}\u00B1{:.2f}, "
        "lw_aspect={:5.2f}\u00B1{:.2f}".format(
            r["category_name"][:27], r["num_annotations"], r["width_mean"], r["width_std"], r["length_mean"],
            r["length_std"], r["height_mean"], r["height_std"], r["lw_aspect_mean"], r["lw_aspect_std"])
        for r in ours.iter_rows(named=True)]
    assert lines == printed(NuScenesExplorer(nusc).list_categories)


def test_class_distribution_numbers_equal_numpy_on_devkit_records(nusc, extract_out):
    ours = rows_by(queries.class_distribution(nuparquet.open(extract_out)).collect(), "category_name")
    stats, instances = defaultdict(list), defaultdict(set)
    for record in nusc.sample_annotation:  # exactly as list_categories builds its arrays
        stats[record["category_name"]].append(record["size"] + [record["size"][1] / record["size"][0]])
        instances[record["category_name"]].add(record["instance_token"])
    assert sorted(ours) == sorted(stats)
    for name, values in stats.items():
        values = np.array(values)
        row = ours[name]
        assert row["num_annotations"] == len(values) and row["num_instances"] == len(instances[name])
        for i, column in enumerate(("width", "length", "height", "lw_aspect")):
            assert row[f"{column}_mean"] == pytest.approx(np.mean(values[:, i]), rel=1e-12)
            assert row[f"{column}_std"] == pytest.approx(np.std(values[:, i]), rel=1e-9, abs=1e-12)


def test_attribute_counts_print_exactly_what_devkit_list_attributes_prints(nusc, extract_out):
    ours = queries.attribute_counts(nuparquet.open(extract_out)).collect()
    assert [f"{r['attribute_name']}: {r['count']}" for r in ours.iter_rows(named=True)] == printed(nusc.list_attributes)


def test_scene_summary_prints_exactly_what_devkit_list_scenes_prints(nusc, extract_out):
    ours = queries.scene_summary(nuparquet.open(extract_out)).collect()
    lines = []
    for r in ours.iter_rows(named=True):  # list_scenes' own formatting, fed with our columns
        desc = r["name"] + ", " + r["description"]
        desc = desc[:51] + "..." if len(desc) > 55 else desc
        lines.append("{:16} [{}] {:4.0f}s, {}, #anns:{}".format(
            desc, r["start_utc"].strftime("%y-%m-%d %H:%M:%S"), r["duration_s"], r["log_location"][:18],
            r["num_annotations_list_scenes"]))
    assert lines == printed(nusc.list_scenes)


def test_class_distribution_by_scene_counts_equal_devkit_sample_walk(nusc, extract_out):
    ours = queries.class_distribution(nuparquet.open(extract_out), by_scene=True).collect()
    expected = Counter()
    for scene in nusc.scene:
        token = scene["first_sample_token"]
        while token:
            sample = nusc.get("sample", token)
            for ann in sample["anns"]:
                expected[(scene["name"], nusc.get("sample_annotation", ann)["category_name"])] += 1
            token = sample["next"]
    assert {(r["scene_name"], r["category_name"]): r["num_annotations"] for r in ours.iter_rows(named=True)} == expected


