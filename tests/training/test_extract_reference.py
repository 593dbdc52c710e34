"""`Samples` over the real two-scene extract against mmdetection3d v1.4.0's own v2 infos for it
(../shared/data/nuscenes-extract-mmdet3d, written by mmdetection3d's converter, not by this library): every box,
label and point count of the 81 samples, and for a few samples the keyframe points (np.fromfile of the file),
the images (cv2.imread) and the camera matrices (BEVFusion's loader restated). The extract holds no sweep files,
so sweeps are checked on the synthetic data (test_samples.py)."""

from __future__ import annotations

import pickle
from pathlib import Path

import cv2
import numpy as np
import pytest

from nuparquet.training.samples import Samples

REFERENCE = Path(__file__).resolve().parents[3] / "shared" / "data" / "nuscenes-extract-mmdet3d"


@pytest.fixture(scope="session")
def extract_reference_infos(extract_root) -> dict:
    if not REFERENCE.is_dir():
        pytest.skip("mmdetection3d reference output not present")
    infos = pickle.loads((REFERENCE / "nuscenes_infos_val_v2.pkl").read_bytes())
    return {entry["token"]: entry for entry in infos["data_list"]}


def test_extract_boxes_equal_mmdet3d_reference_instances(extract_out, extract_reference_infos):
    samples = Samples(extract_out, "val", version="v1.0-mini", lidar=False, cameras=(), sweeps=0, box_filter=None)
    assert sorted(samples.sample_token.tolist()) == sorted(extract_reference_infos)
    valid = Samples(extract_out, "val", version="v1.0-mini", lidar=False, cameras=(), sweeps=0)
    for i in range(len(samples)):
        item, kept = samples[i], valid[i]
        instances = extract_reference_infos[item["sample_token"]]["instances"]
        boxes = np.array([a["bbox_3d"] for a in instances], dtype=np.float32).reshape(-1, 7)
        boxes[:, 2] -= boxes[:, 5] / 2  # LiDARInstance3DBoxes(origin=(0.5, 0.5, 0.5)) to the bottom centre
        velocity = np.array([a["velocity"] for a in instances], dtype=np.float64).reshape(-1, 2)
        velocity[np.isnan(velocity[:, 0])] = 0.0
        np.testing.assert_array_equal(item["gt_bboxes_3d"], np.concatenate([boxes, velocity.astype(np.float32)], 1))
        assert item["gt_labels_3d"].tolist() == [a["bbox_label_3d"] for a in instances]
        assert item["num_lidar_pts"].tolist() == [a["num_lidar_pts"] for a in instances]
        flags = np.array([a["bbox_3d_isvalid"] for a in instances], dtype=bool)
        np.testing.assert_array_equal(kept["gt_bboxes_3d"], item["gt_bboxes_3d"][flags])


def test_extract_points_images_and_camera_matrices_equal_mmdet3d(extract_out, extract_root, extract_reference_infos):
    samples = Samples(extract_out, "val", version="v1.0-mini", sweeps=0, boxes=False)
    for i in (0, 40, len(samples) - 1):
        item = samples[i]
        entry = extract_reference_infos[item["sample_token"]]
        points = np.fromfile(extract_root / "samples" / "LIDAR_TOP" / entry["lidar_points"]["lidar_path"],
                             dtype=np.float32).reshape(-1, 5)
        points[:, 4] = 0  # LoadPointsFromMultiSweeps: the keyframe's fifth channel is the time lag, 0
        np.testing.assert_array_equal(item["points"], points)
        assert list(entry["images"]) == list(samples.cameras)
        for k, (channel, cam) in enumerate(entry["images"].items()):
            np.testing.assert_array_equal(item["img"][k],
                                          cv2.imread(str(extract_root / "samples" / channel / cam["img_path"])))
            lidar2cam_array = np.array(cam["lidar2cam"]).astype(np.float32)
            cam2img_array = np.eye(4).astype(np.float32)
            cam2img_array[:3, :3] = np.array(cam["cam2img"]).astype(np.float32)
            np.testing.assert_array_equal(item["cam2img"][k], cam2img_array)
            np.testing.assert_array_equal(item["lidar2cam"][k], np.array(cam["lidar2cam"]))
            np.testing.assert_array_equal(item["lidar2img"][k], cam2img_array @ lidar2cam_array)
