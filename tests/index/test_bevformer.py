"""`nuparquet index --format bevformer` on the real extract (with its real CAN bus files) against what
BEVFormer's `tools/data_converter/nuscenes_converter.py` (commit 13db21e) builds: its file names, its info keys
in its order, prev/next/scene_token/frame_idx from the sample table walked in table order, its box layout
(from the v1 boxes, which test_reference.py checks against mmdetection3d), and `_get_can_bus_info`'s vector,
recomputed here by its own loop over the CAN bus files."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

import nuparquet
from nuparquet.index import IndexOptions, build_index
from references import bevformer_can_bus

BEVFORMER_KEYS = ["lidar_path", "token", "prev", "next", "can_bus", "frame_idx", "sweeps", "cams", "scene_token",
                  "lidar2ego_translation", "lidar2ego_rotation", "ego2global_translation", "ego2global_rotation",
                  "timestamp", "gt_boxes", "gt_names", "gt_velocity", "num_lidar_pts", "num_radar_pts", "valid_flag"]


def _get_can_bus_info(root, scene_name, sample_timestamp):
    """The converter's function with NuScenesCanBus.get_messages inlined (a fresh json.load per call)."""
    path = root / "can_bus" / f"{scene_name}_pose.json"
    return bevformer_can_bus(json.loads(path.read_text()) if path.exists() else None, sample_timestamp)


@pytest.fixture(scope="module")
def built(extract_root, extract_out, tmp_path_factory):
    ds = nuparquet.open(extract_out)
    bev, v1 = tmp_path_factory.mktemp("bev"), tmp_path_factory.mktemp("v1")
    build_index(ds, str(bev), IndexOptions(format="bevformer", info_version=1, parquet=False))
    build_index(ds, str(v1), IndexOptions(info_version=1, parquet=False))
    return extract_root, bev, v1


def test_bevformer_infos_follow_its_converter(built):
    root, bev, v1 = built
    assert sorted(p.name for p in bev.iterdir()) == ["nuscenes_infos_temporal_train.pkl", "nuscenes_infos_temporal_val.pkl"]
    version = "v1.0-mini-extract"
    samples = json.loads((root / version / "sample.json").read_text())
    scenes = {s["token"]: s["name"] for s in json.loads((root / version / "scene.json").read_text())}
    frame_idx, expected_idx = 0, {}
    for sample in samples:  # the converter's walk over nusc.sample, in table order
        expected_idx[sample["token"]] = frame_idx
        frame_idx = 0 if sample["next"] == "" else frame_idx + 1
    by_token = {s["token"]: s for s in samples}
    seen = 0
    for split in ("train", "val"):
        ours = pickle.loads((bev / f"nuscenes_infos_temporal_{split}.pkl").read_bytes())
        plain = pickle.loads((v1 / f"nuscenes_infos_{split}.pkl").read_bytes())
        assert ours["metadata"] == plain["metadata"]
        assert [i["token"] for i in ours["infos"]] == [i["token"] for i in plain["infos"]]
        for info, base in zip(ours["infos"], plain["infos"]):
            sample = by_token[info["token"]]
            assert list(info) == BEVFORMER_KEYS
            assert (info["prev"], info["next"], info["scene_token"]) == (sample["prev"], sample["next"], sample["scene_token"])
            assert info["frame_idx"] == expected_idx[info["token"]]
            np.testing.assert_array_equal(info["can_bus"], _get_can_bus_info(root, scenes[sample["scene_token"]],
                                                                             sample["timestamp"]))
            b = base["gt_boxes"]
            np.testing.assert_array_equal(info["gt_boxes"], np.concatenate(
                [b[:, :3], b[:, [4, 3, 5]], -b[:, 6:7] - np.pi / 2], axis=1))
            for key in ("sweeps", "cams", "lidar_path", "timestamp", "gt_names"):
                assert repr(info[key]) == repr(base[key]), key
            seen += 1
    assert seen == len(samples)


def test_bevformer_infos_carry_its_can_bus_vector_on_synthetic_data(synth_root, synth_out, tmp_path):
    """The same walk on the synthetic set (no real data), whose CAN bus covers every scene but the last: each info
    has BEVFormer's keys in its order and `_get_can_bus_info`'s vector, zeros where the scene has no pose file."""
    build_index(synth_out, str(tmp_path), IndexOptions(version="v1.0-trainval", format="bevformer",
                                        info_version=1, parquet=False, split="train"))
    ours = pickle.loads((tmp_path / "nuscenes_infos_temporal_train.pkl").read_bytes())["infos"]
    version = next(p for p in synth_root.iterdir() if (p / "sample.json").is_file())
    samples = {s["token"]: s for s in json.loads((version / "sample.json").read_text())}
    scenes = {s["token"]: s["name"] for s in json.loads((version / "scene.json").read_text())}
    assert len(ours) == len(samples)
    without = 0
    for info in ours:
        sample = samples[info["token"]]
        assert list(info) == BEVFORMER_KEYS
        expected = _get_can_bus_info(synth_root, scenes[sample["scene_token"]], sample["timestamp"])
        np.testing.assert_array_equal(info["can_bus"], expected)
        without += not expected.any()
    assert 0 < without < len(ours)
