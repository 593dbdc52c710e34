"""`Samples(bev_map=True)`'s `gt_masks_bev` against bevfusion's own code (mit-han-lab/bevfusion, commit
1ea4ea5ff8d2d1c2ed1b9bc7e3e7a4d26a6b1f0a-era main: `mmdet3d/datasets/nuscenes_dataset.py` `get_data_info`'s
`ego2global`/`lidar2ego` restated below, `mmdet3d/datasets/pipelines/loading.py` `LoadBEVSegmentation` as
tests/parity/map_clients.py restates it), run on
the devkit's `NuScenes` and `NuScenesMap` over the same generated dataroot (6 scenes over its two maps): every
sample of both splits, pixel for pixel."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import SYNTH_VERSION
from nuparquet.training.samples import Samples
from tests.parity.map_clients import LoadBEVSegmentation


def bevfusion_data(nusc, sample) -> dict:
    """What `get_data_info` gives the transform, from the infos its converter writes (the lidar keyframe's
    calibrated_sensor and ego pose); no augmentation (`lidar_aug_matrix` the identity, as in its test pipeline)."""
    from pyquaternion import Quaternion

    sd_rec = nusc.get("sample_data", sample["data"]["LIDAR_TOP"])
    cs_record = nusc.get("calibrated_sensor", sd_rec["calibrated_sensor_token"])
    pose_record = nusc.get("ego_pose", sd_rec["ego_pose_token"])
    info = {"lidar2ego_translation": cs_record["translation"], "lidar2ego_rotation": cs_record["rotation"],
            "ego2global_translation": pose_record["translation"], "ego2global_rotation": pose_record["rotation"],
            "location": nusc.get("log", nusc.get("scene", sample["scene_token"])["log_token"])["location"]}
    data = dict(location=info["location"])
    ego2global = np.eye(4).astype(np.float32)
    ego2global[:3, :3] = Quaternion(info["ego2global_rotation"]).rotation_matrix
    ego2global[:3, 3] = info["ego2global_translation"]
    data["ego2global"] = ego2global
    lidar2ego = np.eye(4).astype(np.float32)
    lidar2ego[:3, :3] = Quaternion(info["lidar2ego_rotation"]).rotation_matrix
    lidar2ego[:3, 3] = info["lidar2ego_translation"]
    data["lidar2ego"] = lidar2ego
    data["lidar_aug_matrix"] = np.eye(4).astype(np.float32)
    return data


@pytest.fixture(scope="module")
def map_nusc(map_root, devkit):
    return devkit.NuScenes(SYNTH_VERSION, str(map_root), verbose=False)


CLASSES = ("drivable_area", "ped_crossing", "walkway", "stop_line", "carpark_area", "divider")


@pytest.mark.parametrize("classes, bound", [(CLASSES, (-50.0, 50.0, 0.5)),
                                            (("drivable_area*", "divider", "lane"), (-30.0, 30.0, 0.25))])
def test_masks_equal_bevfusions_load_bev_segmentation(map_out, map_nusc, devkit_maps, classes, bound):
    transform = LoadBEVSegmentation(devkit_maps, bound, bound, classes)
    painted, locations = np.zeros(len(classes), dtype=np.int64), set()
    for split in ("train", "val"):
        samples = Samples(map_out, split, lidar=False, cameras=(), boxes=False, bev_map=True, bev_classes=classes,
                          bev_xbound=bound, bev_ybound=bound, version="v1.0-trainval")
        for i in range(len(samples)):
            item = samples[i]
            sample = map_nusc.get("sample", item["sample_token"])
            data = bevfusion_data(map_nusc, sample)
            expected = transform(data)["gt_masks_bev"]
            assert item["gt_masks_bev"].dtype == np.uint8 and item["gt_masks_bev"].shape == expected.shape
            np.testing.assert_array_equal(item["gt_masks_bev"], expected)
            painted += expected.reshape(len(classes), -1).sum(axis=1)
            locations.add(data["location"])
    assert locations == set(devkit_maps)  # every map of the dataroot
    side = int((bound[1] - bound[0]) / bound[2])
    assert expected.shape == (len(classes), side, side)
    assert (painted > 0).all()  # every class painted somewhere: no empty mask passes


def test_the_lidar_pose_equals_bevfusions(map_out, map_nusc):
    """The float32 lidar2global both build: the same to a float32 step (their rotation matrices are BLAS products)."""
    from nuparquet.training.bev_map import lidar2global

    samples = Samples(map_out, "train", lidar=False, cameras=(), boxes=False, bev_map=True, version="v1.0-trainval")
    for s in range(len(samples)):
        data = bevfusion_data(map_nusc, map_nusc.get("sample", samples.sample_token[s]))
        expected = data["ego2global"] @ data["lidar2ego"] @ np.linalg.inv(data["lidar_aug_matrix"])
        ours = lidar2global(samples._lidar_t[s], samples._lidar_q[s], samples._ego_t[s], samples._ego_q[s])
        assert ours.dtype == expected.dtype == np.float32
        np.testing.assert_array_max_ulp(ours, expected, maxulp=1)
