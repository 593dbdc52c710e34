"""nuScenes-lidarseg in the training index, against mmdetection3d v1.4.0's converter re-stated with the devkit
(`mmdet3d_restated.py`: `create_nuscenes_infos` with its lidarseg lines, then `update_nuscenes_infos`) on a
synthetic dataset with lidarseg labels: `pts_semantic_mask_path` in every non-test v1 info (last, after
`valid_flag`: the dataroot-joined path) and v2 entry (after `instances`, before `cam_instances`: the file
name), in the corrected pickle and the Parquet infos, and nowhere else (no lidarseg table, a test version,
BEVFormer's format)."""

from __future__ import annotations

import copy
import json
import pickle
import shutil

import numpy as np
import polars as pl
import pytest

from conftest import SYNTH_VERSION
from mmdet3d_restated import run_restated
from nuparquet.dataset import Dataset, open_dataset
from nuparquet.errors import InputError
from nuparquet.index import IndexOptions, build_index
from test_reference import assert_same

KEY = "pts_semantic_mask_path"


@pytest.fixture(scope="module")
def restated_v14(devkit, lidarseg_root, tmp_path_factory):
    return run_restated(tmp_path_factory.mktemp("v14"), lidarseg_root, SYNTH_VERSION, "v1.0-trainval", "v14")


@pytest.fixture(scope="module")
def built(lidarseg_out, tmp_path_factory):
    out = tmp_path_factory.mktemp("lidarseg-index")
    ds = open_dataset(lidarseg_out)
    build_index(ds, str(out / "v1"), IndexOptions(version="v1.0-trainval", info_version=1))
    build_index(ds, str(out / "v2"), IndexOptions(version="v1.0-trainval", corrected=True))
    return out


def _load(path):
    return pickle.loads(path.read_bytes())


def _without_float32(info: dict) -> tuple[dict, list[float]]:
    """(a copy of a v2 entry without the cam_instances' center_2d and depth, those values): v1.4.0 computes them
    in torch float32, the re-statement in numpy float32, so they are compared with float32 tolerance."""
    info = copy.deepcopy(info)
    values = []
    for instances in info.get("cam_instances", {}).values():
        for inst in instances:
            values += inst.pop("center_2d") + [inst.pop("depth")]
    return info, values


def test_v1_infos_equal_the_converter(built, restated_v14):
    for split in ("train", "val"):
        ours = _load(built / "v1" / f"nuscenes_infos_{split}.pkl")
        ref = _load(restated_v14 / "v14" / "v1" / f"nuscenes_infos_{split}.pkl")
        assert ref["infos"] and all(KEY in info for info in ref["infos"])  # the data reach the case
        assert_same(ours, ref, rounding=True)


def test_v2_infos_equal_the_converter(built, restated_v14):
    for split in ("train", "val"):
        ours = _load(built / "v2" / f"nuscenes_infos_{split}.pkl")
        ref = _load(restated_v14 / "v14" / "v2" / f"nuscenes_infos_{split}.pkl")
        assert list(ours) == list(ref) and ours["metainfo"] == ref["metainfo"]
        assert len(ours["data_list"]) == len(ref["data_list"]) > 0
        for a, b in zip(ours["data_list"], ref["data_list"]):
            (a, a32), (b, b32) = _without_float32(a), _without_float32(b)
            assert_same(a, b, rounding=True)
            np.testing.assert_allclose(a32, b32, rtol=1e-6)
        assert sum(len(v) for e in ref["data_list"] for v in e["cam_instances"].values()) > 0


def test_parquet_rows_equal_the_converter(lidarseg_out, restated_v14, tmp_path):
    """DIR/infos/ against v1.4.0's v2 entries (re-stated): every field of every row, the camera instances with all
    their fields (center_2d and depth to float32 tolerance), the sweeps with their float32-rounded lidar2sensor.
    Built here, not by the module's fixture, so that the mutation runs map the Parquet writer to this test."""
    build_index(lidarseg_out, str(tmp_path), IndexOptions(version="v1.0-trainval"))
    for split in ("train", "val"):
        ref = _load(restated_v14 / "v14" / "v2" / f"nuscenes_infos_{split}.pkl")["data_list"]
        rows = pl.read_parquet(tmp_path / "infos" / f"{split}.parquet").to_dicts()
        assert len(rows) == len(ref) > 0
        for row, entry in zip(rows, ref):
            assert row["split"] == split
            for key in ("sample_idx", "token", "timestamp", "ego2global", "images", "lidar_points", KEY):
                assert_same(row[key], entry[key], key, key, check_types=False, rounding=True)
            assert_same(row["lidar_sweeps"], entry.get("lidar_sweeps", []), "lidar_sweeps", check_types=False,
                        rounding=True)
            assert_same([{k: v for k, v in i.items() if k != "velocity_valid"} for i in row["instances"]],
                        entry["instances"], "instances", check_types=False, rounding=True)
            (a, a32), (b, b32) = (_without_float32({"cam_instances": e["cam_instances"]}) for e in (row, entry))
            assert_same(a, b, "cam_instances", check_types=False, rounding=True)
            np.testing.assert_allclose(a32, b32, rtol=1e-6)
        # the data reach the cases: sweeps, camera instances, and velocities other than zero
        assert any("lidar_sweeps" in e for e in ref)
        velocities = [v for e in ref for c in e["cam_instances"].values() for i in c for v in i["velocity"]]
        assert velocities and any(np.isfinite(v) and v != 0 for v in velocities)


def test_the_key_from_the_tables(built, lidarseg_root):
    """Independently of any converter: the label file of each sample's LIDAR_TOP keyframe (lidarseg.json,
    record token = the reading's token), in the places the converter puts it."""
    tables = lidarseg_root / SYNTH_VERSION
    records = {r["token"]: r["filename"] for r in json.loads((tables / "lidarseg.json").read_text())}
    keyframe = {r["sample_token"]: r["token"] for r in json.loads((tables / "sample_data.json").read_text())
                if r["is_key_frame"] and r["filename"].startswith("samples/LIDAR_TOP/")}
    seen = 0
    for split in ("train", "val"):
        v1 = _load(built / "v1" / f"nuscenes_infos_{split}.pkl")["infos"]
        v2 = _load(built / "v2" / f"nuscenes_infos_{split}.pkl")["data_list"]
        for info, entry in zip(v1, v2, strict=True):
            filename = records[keyframe[info["token"]]]
            assert list(info)[-2:] == ["valid_flag", KEY] and info[KEY] == f"./data/nuscenes/{filename}"
            keys = list(entry)
            assert keys[keys.index("instances") + 1:] == [KEY, "cam_instances"]
            assert entry[KEY] == filename.rsplit("/", 1)[1] and entry[KEY].endswith("_lidarseg.bin")
            seen += 1
    assert seen == len(keyframe) == 12


def test_corrected_pickle_and_parquet_carry_it(built):
    for split in ("train", "val"):
        entries = _load(built / "v2" / f"nuscenes_infos_{split}.pkl")["data_list"]
        fixed = _load(built / "v2" / f"nuscenes_infos_{split}_corrected.pkl")["data_list"]
        rows = pl.read_parquet(built / "v2" / "infos" / f"{split}.parquet")
        assert [e[KEY] for e in fixed] == [e[KEY] for e in entries] == rows[KEY].to_list()
        assert rows.columns.index(KEY) == rows.columns.index("instances") + 1


def test_absent_without_lidarseg_and_in_a_test_version(lidarseg_out, tmp_path):
    ds = open_dataset(lidarseg_out)
    without = Dataset(ds.root, dict(ds.manifest, datasets={k: v for k, v in ds.manifest["datasets"].items()
                                                           if k != "tables/lidarseg"}))
    build_index(without, str(tmp_path / "v2"), IndexOptions(version="v1.0-trainval"))
    build_index(without, str(tmp_path / "v1"), IndexOptions(version="v1.0-trainval", info_version=1))
    assert not any(KEY in e for e in _load(tmp_path / "v2" / "nuscenes_infos_train.pkl")["data_list"])
    assert not any(KEY in i for i in _load(tmp_path / "v1" / "nuscenes_infos_train.pkl")["infos"])
    assert pl.read_parquet(tmp_path / "v2" / "infos" / "train.parquet")[KEY].null_count() == 8
    # a test version: the converter's lidarseg lines are inside `if not test`
    build_index(ds, str(tmp_path / "test"), IndexOptions(version="v1.0-test"))
    entries = _load(tmp_path / "test" / "nuscenes_infos_test.pkl")["data_list"]
    assert len(entries) == 12 and not any(KEY in e for e in entries)


def test_a_reading_without_a_record_is_an_input_error(lidarseg_out, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(lidarseg_out, out)
    folder = out / "tables" / "lidarseg"
    table = pl.read_parquet(folder / "**" / "*.parquet")
    dropped = table["token"][5]
    shutil.rmtree(folder)
    folder.mkdir()
    table.filter(pl.col("token") != dropped).write_parquet(folder / "part-0.parquet")
    with pytest.raises(InputError, match=f"no record for the keyframe lidar reading {dropped}"):
        build_index(out, str(tmp_path / "index"), IndexOptions(version="v1.0-trainval"))
    # BEVFormer's and 0.17's converters never look lidarseg up
    build_index(out, str(tmp_path / "legacy"), IndexOptions(version="v1.0-trainval", format="mmdet3d-legacy"))


def test_bevformer_infos_have_no_lidarseg_key(synth_out, tmp_path):
    build_index(synth_out, str(tmp_path / "v1"), IndexOptions(version="v1.0-trainval", info_version=1))
    build_index(synth_out, str(tmp_path / "bev"), IndexOptions(version="v1.0-trainval", info_version=1,
                                        format="bevformer"))
    assert all(KEY in i for i in _load(tmp_path / "v1" / "nuscenes_infos_train.pkl")["infos"])
    assert not any(KEY in i for i in _load(tmp_path / "bev" / "nuscenes_infos_temporal_train.pkl")["infos"])
