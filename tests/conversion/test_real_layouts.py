"""Real derived datasets' layouts (hand-built from a synthetic dataset the way the real files differ; real Lyft
and T4 files stay out of the repository): Lyft Level 5's missing or NaN width/height, empty visibility tokens,
per-record key orders, integers in float lists, fields present in some records only, one integer written as a
float; TIER IV T4's version folder called `annotation`, extra tables, hashed visibility tokens with worded levels.
Each converts, validates clean, and comes back exactly from `export-json`."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import polars as pl
import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main
from nuparquet.conversion import convert
from nuparquet.export.json_files import export_json


def load(folder: Path, table: str) -> list[dict]:
    return json.loads((folder / f"{table}.json").read_text())


def save(folder: Path, table: str, records) -> None:
    (folder / f"{table}.json").write_text(json.dumps(records))  # NaN written as the literal NaN, as Lyft does


@pytest.fixture(scope="module")
def lyft_like(synth_root, tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("lyft-layout") / "data"
    shutil.copytree(synth_root / SYNTH_VERSION, root / SYNTH_VERSION)
    folder = root / SYNTH_VERSION
    sensors = {s["token"]: s["modality"] for s in load(folder, "sensor")}
    calibrations = load(folder, "calibrated_sensor")
    modality = {c["token"]: sensors[c["sensor_token"]] for c in calibrations}
    sample_data = load(folder, "sample_data")
    for sd in sample_data:
        if modality[sd["calibrated_sensor_token"]] == "radar":
            del sd["width"], sd["height"]  # absent keys
        elif modality[sd["calibrated_sensor_token"]] == "lidar":
            sd["width"], sd["height"] = math.nan, math.nan  # NaN literals
    sample_data[5]["timestamp"] = float(sample_data[5]["timestamp"])  # one integer written as a float
    save(folder, "sample_data", sample_data)
    annotations = load(folder, "sample_annotation")
    for a in annotations:
        a["visibility_token"] = ""
    save(folder, "sample_annotation", annotations)
    samples = load(folder, "sample")
    for i in range(3):
        samples[i] = dict(reversed(list(samples[i].items())))  # another key order
    save(folder, "sample", samples)
    lidar = next(c for c in calibrations if modality[c["token"]] == "lidar")
    lidar["rotation"] = [1, 0, 0, 0]  # integers inside a float list
    camera = next(c for c in calibrations if modality[c["token"]] == "camera")
    camera["camera_intrinsic"] = [[1266, 0.0, 816.5], [0, 1266.4, 491], [0, 0, 1]]
    save(folder, "calibrated_sensor", calibrations)
    logs = load(folder, "log")
    logs[0]["map_token"] = "only here"  # a field present in some records only
    save(folder, "log", logs)
    return root


@pytest.fixture(scope="module")
def t4_like(synth_root, tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("t4-layout") / "data"
    folder = root / "annotation"
    shutil.copytree(synth_root / SYNTH_VERSION, folder)
    levels = [("full", "No occlusion"), ("most", "Object is occluded between 0 and 50%"),
              ("partial", "Object is occluded between 50 and 90%"), ("none", "Object is fully occluded")]
    hashed = {str(i + 1): f"{i + 1:02d}" + "a3f9" * 7 for i in range(4)}
    save(folder, "visibility", [{"token": hashed[str(i + 1)], "level": level, "description": description}
                                for i, (level, description) in enumerate(levels)])
    annotations = load(folder, "sample_annotation")
    for a in annotations:
        a["visibility_token"] = hashed[a["visibility_token"]]
    save(folder, "sample_annotation", annotations)
    sample_data = load(folder, "sample_data")
    save(folder, "object_ann", [{"token": f"oa{i}", "sample_data_token": sd["token"], "bbox": [10, 20.5, 30, 40],
                                 "mask": {"size": [900, 1600], "counts": "abc"}, "category_token": "x"}
                                for i, sd in enumerate(sample_data[:5])])
    save(folder, "vehicle_state", [{"token": "vs0", "timestamp": 1, "accel": 0, "speed": 1.5},
                                   {"token": "vs1", "timestamp": 2, "accel": 0.25, "speed": 2}])
    save(folder, "surface_ann", [])
    return root


def assert_same_json(a, b, where: str) -> None:
    assert type(a) is type(b), where
    if isinstance(a, dict):
        assert list(a) == list(b), f"{where}: key order"
        for k in a:
            assert_same_json(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same_json(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and math.isnan(a):
        assert math.isnan(b), where
    else:
        assert a == b, where


@pytest.mark.parametrize("which, version", [("lyft_like", SYNTH_VERSION), ("t4_like", "annotation")])
def test_converts_validates_and_round_trips_exactly(request, tmp_path, which, version):
    root = request.getfixturevalue(which)
    assert main(["validate", str(root), "--version", version, "--quiet"]) == 0
    convert(root, version, tmp_path / "out")
    export_json(tmp_path / "out", tmp_path / "back")
    originals = sorted((root / version).glob("*.json"))
    assert sorted(p.name for p in (tmp_path / "back" / version).iterdir()) == [p.name for p in originals]
    for path in originals:
        assert_same_json(json.loads(path.read_text()), json.loads((tmp_path / "back" / version / path.name).read_text()),
                         path.name)


def test_lyft_frames_give_non_images_zero_size_and_annotations_no_visibility(lyft_like, tmp_path):
    convert(lyft_like, SYNTH_VERSION, tmp_path / "out")
    frames = pl.read_parquet(tmp_path / "out" / "frames")
    by_modality = frames.group_by(pl.col("modality").cast(pl.String)).agg(pl.col("width").max(), pl.col("height").min())
    sizes = {r["modality"]: (r["width"], r["height"]) for r in by_modality.iter_rows(named=True)}
    assert sizes["lidar"] == (0, 0) and sizes["radar"] == (0, 0) and sizes["camera"] == (1600, 900)
    assert frames.schema["width"] == pl.Int64 and frames.schema["height"] == pl.Int64  # integers again in frames
    annotations = pl.read_parquet(tmp_path / "out" / "annotations")
    assert annotations["visibility_level"].is_null().all() and annotations["visibility_name"].is_null().all()
    table = pl.read_parquet(tmp_path / "out" / "tables" / "sample_data")
    assert table.schema["timestamp"] == pl.Int64  # one float-written integer does not make the column float
    assert table.schema["width"] == pl.Float64  # NaN does


def test_t4_visibility_comes_from_the_table_and_extra_tables_are_kept(t4_like, tmp_path):
    manifest = convert(t4_like, "annotation", tmp_path / "out")
    annotations = pl.read_parquet(tmp_path / "out" / "annotations")
    levels = {v["token"]: v for v in load(t4_like / "annotation", "visibility")}
    source = {a["token"]: levels[a["visibility_token"]] for a in load(t4_like / "annotation", "sample_annotation")}
    for row in annotations.select("token", "visibility_name", "visibility_description", "visibility_level").iter_rows(named=True):
        assert (row["visibility_name"], row["visibility_description"]) == (source[row["token"]]["level"],
                                                                           source[row["token"]]["description"])
        assert row["visibility_level"] is None  # worded levels give no ordinal
    kinds = {f["path"]: f["kind"] for f in manifest["files"]}
    assert kinds["annotation/object_ann.json"] == "table_inferred" and kinds["annotation/sample.json"] == "table"
    object_ann = pl.read_parquet(tmp_path / "out" / "tables" / "object_ann")
    assert object_ann.height == 5 and object_ann.schema["bbox"] == pl.Array(pl.Float64, 4)


def test_nuscenes_visibility_levels_are_ordinals_from_the_table(synth_root, synth_out):
    levels = {v["token"]: v["level"] for v in load(synth_root / SYNTH_VERSION, "visibility")}
    rank = {level: i + 1 for i, level in enumerate(sorted(set(levels.values()), key=lambda l: int(l[1:].split("-")[0])))}
    annotations = pl.read_parquet(synth_out / "annotations")
    for token, level, name in annotations.select("visibility_token", "visibility_level", "visibility_name").unique().iter_rows():
        assert name == levels[token] and level == rank[levels[token]]
