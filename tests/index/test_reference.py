"""The infos against mmdetection3d v1.4.0's own output for the real extract (../shared/data/nuscenes-extract-mmdet3d).

Every key, key order, list length, string, integer, bool and scalar type is compared exactly, and every float
bit for bit (NaN where the reference has NaN): the index replays numpy 1.26 + OpenBLAS's operation order
(`nuparquet/index/blas.py`), whatever BLAS the test machine has. center_2d/depth are float32 arithmetic
(torch in mmdet3d): the issue allows 1e-4 relative there, but they are exact too on this data.
"""

from __future__ import annotations

import json
import math
import pickle
import struct
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from nuparquet.index import IndexOptions, build_index

REFERENCE = Path(__file__).resolve().parents[3] / "shared" / "data" / "nuscenes-extract-mmdet3d"


@pytest.fixture(scope="session")
def reference_dir(extract_root) -> Path:
    if not REFERENCE.is_dir():
        pytest.skip("mmdetection3d reference output not present")
    return REFERENCE


@pytest.fixture(scope="session")
def built(extract_out, tmp_path_factory):
    out = tmp_path_factory.mktemp("index")
    v1 = build_index(extract_out, str(out / "v1"), IndexOptions(info_version=1))
    v2 = build_index(extract_out, str(out / "v2"), IndexOptions(info_version=2, corrected=True))
    return v1, v2


def _same_bits(a: float, b: float) -> bool:
    """Equal to the last bit (and sign of zero); NaN equals NaN."""
    if math.isnan(b):
        return math.isnan(a)
    return struct.pack("<d", a) == struct.pack("<d", b)


def _within_rounding(a: float, b: float) -> bool:
    """Equal but for what the machine's BLAS kernel decides (docs/CONTRACTS.md, "The training index"): within
    1e-9 (metres, radians, pixels), and a value the converter rounded to float32 within one float32 step of it."""
    if math.isnan(b):
        return math.isnan(a)
    bound = 1e-9 + (float(np.spacing(np.float32(abs(b)))) if float(np.float32(b)) == b else 0.0)
    return abs(a - b) <= bound


def assert_same(ours, ref, path="", key="", check_types=True, rounding=False):
    """Every key, key order, length, type and value of `ref` in `ours`; floats to the bit, or with `rounding`
    (a reference computed on this machine by a converter whose products go through BLAS) within its rounding."""
    if isinstance(ref, dict):
        assert isinstance(ours, dict) and list(ours) == list(ref), f"{path}: keys {list(ours)} != {list(ref)}"
        for k in ref:
            assert_same(ours[k], ref[k], f"{path}.{k}", k, check_types, rounding)
    elif isinstance(ref, (list, tuple)):
        assert isinstance(ours, list) and len(ours) == len(ref), f"{path}: length {len(ours)} != {len(ref)}"
        for i, (a, b) in enumerate(zip(ours, ref)):
            assert_same(a, b, f"{path}[{i}]", key, check_types, rounding)
    elif isinstance(ref, np.ndarray):
        assert isinstance(ours, np.ndarray) and ours.shape == ref.shape and ours.dtype == ref.dtype, \
            f"{path}: {getattr(ours, 'dtype', type(ours))} {getattr(ours, 'shape', '')} != {ref.dtype} {ref.shape}"
        assert_same(ours.tolist(), ref.tolist(), path, key, False, rounding)
    elif isinstance(ref, (float, np.floating)):
        if check_types:
            assert type(ours) is type(ref), f"{path}: {type(ours)} != {type(ref)}"
        same = _within_rounding if rounding else _same_bits
        assert same(float(ours), float(ref)), f"{path}: {ours!r} != {ref!r}"
    else:
        if check_types:
            assert type(ours) is type(ref), f"{path}: {type(ours)} != {type(ref)}"
        assert ours == ref, f"{path}: {ours!r} != {ref!r}"


def test_v1_equals_reference(built, reference_dir):
    ours = pickle.loads(built[0]["val"].read_bytes())
    ref = pickle.loads((reference_dir / "nuscenes_infos_val_v1.pkl").read_bytes())
    assert_same(ours, ref)
    assert pickle.loads(built[0]["train"].read_bytes())["infos"] == []  # mini: train is empty, as the converter's


def test_v2_equals_reference_pickle_and_json(built, reference_dir):
    ours = pickle.loads(built[1]["val"].read_bytes())
    ref = pickle.loads((reference_dir / "nuscenes_infos_val_v2.pkl").read_bytes())
    assert_same(ours, ref)
    ref_json = json.loads((reference_dir / "nuscenes_infos_val_v2.json").read_text())["nuscenes_infos_val.pkl"]
    assert_same(ours, ref_json, check_types=False)
    # the quirks are there: sweeps with the data prefix and no feature count, first samples without sweeps
    entries = ours["data_list"]
    assert sum("lidar_sweeps" not in e for e in entries) == 2
    sweep = entries[1]["lidar_sweeps"][0]["lidar_points"]
    assert sweep["lidar_path"].startswith("./data/nuscenes/sweeps/") and sweep["num_pts_feats"] is None


def test_corrected_form_beside(built, reference_dir):
    fixed = pickle.loads((built[1]["val"].parent / "nuscenes_infos_val_corrected.pkl").read_bytes())
    ref = pickle.loads((reference_dir / "nuscenes_infos_val_v2.pkl").read_bytes())
    labels = {i["bbox_label"] for e in ref["data_list"] for i in e["instances"]}
    assert -1 in labels
    unmapped = set(fixed["metainfo"]["categories"]) - set(ref["metainfo"]["categories"])
    assert unmapped == {"movable_object.debris", "vehicle.emergency.police", "static_object.bicycle_rack"}
    sweep = fixed["data_list"][1]["lidar_sweeps"][0]["lidar_points"]
    assert sweep["lidar_path"].startswith("sweeps/") and sweep["num_pts_feats"] == 5
    e2g = np.array(fixed["data_list"][1]["ego2global"])
    assert np.allclose(e2g, ref["data_list"][1]["ego2global"], atol=2e-4)
    assert not np.array_equal(e2g, np.array(e2g, dtype=np.float32))  # float64, not rounded


def test_parquet_rows_carry_the_reference_values(built, reference_dir):
    ref = pickle.loads((reference_dir / "nuscenes_infos_val_v2.pkl").read_bytes())["data_list"]
    rows = pl.read_parquet(built[1]["infos"] / "val.parquet").to_dicts()
    assert len(rows) == len(ref)
    for row, entry in zip(rows, ref):
        assert row["split"] == "val"
        for key in ("sample_idx", "token", "timestamp", "ego2global", "images", "lidar_points", "cam_instances"):
            assert_same(row[key], entry[key], key, key, check_types=False)
        assert_same([{k: v for k, v in i.items() if k != "velocity_valid"} for i in row["instances"]],
                    entry["instances"], "instances", check_types=False)
        assert [i["velocity_valid"] for i in row["instances"]] == \
            [bool(np.isfinite(i["velocity"]).all()) for i in entry["instances"]]
        assert_same(row["lidar_sweeps"], entry.get("lidar_sweeps", []), "lidar_sweeps", check_types=False)
