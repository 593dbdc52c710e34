"""Datasets that reuse the nuScenes layout but differ from it (Lyft Level 5: 64-character tokens, float
timestamps and image sizes, one ego_pose shared by several sample_data, extra fields) convert losslessly."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import polars as pl
import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main
from nuparquet.conversion import convert
from nuparquet.export.json_files import export_json

V = SYNTH_VERSION
TOKEN_FIELDS = {"token", "sample_token", "ego_pose_token", "calibrated_sensor_token", "sensor_token", "scene_token",
                "log_token", "first_sample_token", "last_sample_token", "instance_token", "category_token",
                "first_annotation_token", "last_annotation_token", "prev", "next",
                "sample_data_token"}  # lidarseg.json / panoptic.json (synth --with-lidar writes them)


def lyftify(src: Path, dst: Path) -> None:
    """Rewrite a synthetic nuScenes dataset the way Lyft's differs."""
    def long(token: str) -> str:
        return hashlib.sha256(token.encode()).hexdigest() if token else ""

    (dst / V).mkdir(parents=True)
    for path in (src / V).glob("*.json"):
        records = json.loads(path.read_text())
        for r in records:
            for key in TOKEN_FIELDS & r.keys():
                if path.stem != "visibility":
                    r[key] = long(r[key])
            if "attribute_tokens" in r:
                r["attribute_tokens"] = [long(t) for t in r["attribute_tokens"]]
            if "log_tokens" in r:
                r["log_tokens"] = [long(t) for t in r["log_tokens"]]
            if "timestamp" in r:
                r["timestamp"] = r["timestamp"] + 0.25  # non-integral microseconds
            if path.stem == "sample_data":
                r["width"], r["height"] = float(r["width"]), float(r["height"])
            if path.stem == "log":
                r["map_token"] = "extra field kept as found"
        if path.stem == "sample_data":  # two sample_data share the first one's ego pose
            records[1]["ego_pose_token"] = records[0]["ego_pose_token"]
        (dst / V / path.name).write_text(json.dumps(records))


@pytest.fixture(scope="module")
def lyft_like(synth_root, tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("lyft") / "data"
    lyftify(synth_root, root)
    out = root.parent / "out"
    convert(root, V, out)
    return root, out


def test_lyft_like_dataset_round_trips_exactly(lyft_like, tmp_path):
    root, out = lyft_like
    export_json(out, tmp_path / "json")
    for path in (root / V).glob("*.json"):
        original = json.loads(path.read_text())
        again = json.loads((tmp_path / "json" / V / path.name).read_text())
        assert again == original, path.name
        for a, b in zip(original, again):
            assert list(a) == list(b)
            assert all(type(a[k]) is type(b[k]) for k in a), path.name  # floats stay floats


def test_float_fields_are_kept_as_float64_and_recorded(lyft_like):
    """Non-integral timestamps make the column float64; integral floats (width 1600.0) keep the integer column and
    only their own JSON form (`_json_types`)."""
    _, out = lyft_like
    manifest = json.loads((out / "manifest.json").read_text())
    assert set(manifest["tables"]["sample_data"]["float_fields"]) == {"timestamp"}
    table = pl.read_parquet(out / "tables/sample_data/*.parquet")
    assert table.schema["timestamp"] == pl.Float64
    assert (table["timestamp"] % 1 == 0.25).all()
    assert table.schema["width"] == pl.Int64 and table.schema["height"] == pl.Int64
    assert table["_json_types"].to_list() == [["height", "width"]] * table.height
    # A field the schema does not know is kept as its raw JSON text (and recorded as such).
    assert json.loads(pl.read_parquet(out / "tables/log/*.parquet")["map_token"][0]) == "extra field kept as found"
    assert manifest["tables"]["log"]["json_fields"] == ["map_token"]


def test_shared_ego_pose_joins_into_both_frames(lyft_like):
    root, out = lyft_like
    sample_data = json.loads((root / V / "sample_data.json").read_text())
    frames = pl.read_parquet(out / "frames/*.parquet")
    shared = frames.filter(pl.col("token").is_in([sample_data[0]["token"], sample_data[1]["token"]]))
    assert shared.height == 2 and shared["ego_translation"].n_unique() == 1
    assert frames["token"].str.len_chars().unique().to_list() == [64]
    assert frames.schema["timestamp"] == pl.Int64 and frames.schema["width"] == pl.Int64


def test_non_integral_count_field_is_an_error_naming_table_field_and_record(synth_root, tmp_path, capsys):
    shutil.copytree(synth_root / V, tmp_path / "data" / V)
    path = tmp_path / "data" / V / "instance.json"
    records = json.loads(path.read_text())
    records[0]["nbr_annotations"] = records[0]["nbr_annotations"] + 0.5
    path.write_text(json.dumps(records))
    assert main(["validate", str(tmp_path / "data"), "--version", V]) == 1
    out = capsys.readouterr().out
    assert f"instance.json[0] token={records[0]['token']}: field 'nbr_annotations' must be an integer" in out
