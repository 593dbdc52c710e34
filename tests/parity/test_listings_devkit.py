"""Devkit parity of the listings: the canned queries print exactly what nuscenes-devkit's list_categories,
list_attributes and list_scenes print, and count what its sample walk counts (real extract)."""

from __future__ import annotations

import contextlib
import io
from collections import Counter, defaultdict

import numpy as np
import pytest

import nuparquet
from conftest import EXTRACT_VERSION
from nuparquet import queries


@pytest.fixture(scope="module")
def nusc(devkit, extract_root):
    return devkit.NuScenes(version=EXTRACT_VERSION, dataroot=str(extract_root), verbose=False)


def printed(function) -> list[str]:
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        function()
    return buffer.getvalue().splitlines()


def rows_by(df, *keys: str) -> dict:
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


