"""The optional parts of `Samples` against the references themselves, run on the devkit's `NuScenes` over the same
generated dataroot:

- `sweeps_as="devkit"`: the devkit's `LidarPointCloud.from_file_multisweep(nusc, sample, "LIDAR_TOP", "LIDAR_TOP",
  nsweeps=sweeps + 1, min_distance)`; x, y, z within one float32 step (its transform is a BLAS float64 product
  rounded to float32: docs/CONTRACTS.md), intensity and the time column exact.
- radar: the devkit's `RadarPointCloud.from_file_multisweep(nusc, sample, chan, "LIDAR_TOP", nsweeps, 1.0)` of each
  radar in the rig's order, concatenated, its `times` appended, as float32: x, y, z within one float32 step,
  every other field and the time exact.
- the CAN bus vector: BEVFormer's `_get_can_bus_info` (tests/parity/can_bus_clients.py) on the devkit's
  `NuScenesCanBus`, then its `get_data_info` patch restated below; the 16 copied values exact, the two angles
  within 1e-12 (the devkit's `quaternion_yaw` goes through pyquaternion's BLAS product).
- the queue: BEVFormer's `union2one` restated below over the restated vectors, at every sample (scene starts and
  ends, the split's first sample)."""

from __future__ import annotations

import copy
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from conftest import SYNTH_VERSION
from nuparquet.training.samples import Samples

SWEEPS = 3
TRAIN = dict(version="v1.0-trainval")


def _can_bus_clients():
    path = Path(__file__).resolve().parents[1] / "parity" / "can_bus_clients.py"
    spec = importlib.util.spec_from_file_location("can_bus_clients", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def nusc(synth_root, devkit):
    return devkit.NuScenes(SYNTH_VERSION, str(synth_root), verbose=False)


def _sample(nusc, token):
    return nusc.get("sample", token)


# --- lidar sweeps as the devkit aggregates them -------------------------------------------------------------------

@pytest.mark.parametrize("min_distance", [1.0, 4.0])
def test_devkit_sweeps_equal_from_file_multisweep(synth_out, nusc, min_distance):
    from nuscenes.utils.data_classes import LidarPointCloud

    samples = Samples(synth_out, "train", sweeps=SWEEPS, sweeps_as="devkit", cameras=(), boxes=False,
                      close_radius_m=min_distance, **TRAIN)
    seen, removed = set(), 0
    for i in range(len(samples)):
        item = samples[i]
        sample = _sample(nusc, item["sample_token"])
        pc, times = LidarPointCloud.from_file_multisweep(nusc, sample, "LIDAR_TOP", "LIDAR_TOP", nsweeps=SWEEPS + 1,
                                                         min_distance=min_distance)
        points = item["points"]
        assert points.dtype == np.float32 and points.shape == (pc.points.shape[1], 5)
        np.testing.assert_array_max_ulp(points[:, :3], pc.points[:3].T, maxulp=1)
        np.testing.assert_array_equal(points[:, 3], pc.points[3])
        np.testing.assert_array_equal(points[:, 4], times[0].astype(np.float32))
        assert item["lidar_sweeps"] == len(np.unique(times)) - 1
        seen.add(item["lidar_sweeps"])
        keyframe = LidarPointCloud.from_file(str(Path(nusc.dataroot) / nusc.get(
            "sample_data", sample["data"]["LIDAR_TOP"])["filename"]))
        removed += keyframe.nbr_points() - int((times[0] == 0).sum())
    assert seen == {0, SWEEPS}  # a scene's first sample has none (the devkit's prev chain ends)
    if min_distance > 1.0:
        assert removed > 0  # the keyframe's own close points leave too (mmdetection3d keeps them)


# --- radar ---------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("filters", [True, False])
def test_radar_points_equal_the_devkits_multisweep_of_every_radar(synth_out, nusc, filters):
    from nuscenes.utils.data_classes import RadarPointCloud

    samples = Samples(synth_out, "train", lidar=False, cameras=(), boxes=False, radars="all", radar_sweeps=2,
                      radar_filters=filters, **TRAIN)
    assert samples.radars == ("RADAR_BACK_LEFT", "RADAR_BACK_RIGHT", "RADAR_FRONT", "RADAR_FRONT_LEFT",
                              "RADAR_FRONT_RIGHT")
    if not filters:
        RadarPointCloud.disable_filters()
    try:
        total = 0
        for i in (0, 1, 5, 6, len(samples) - 1):
            item = samples[i]
            parts = []
            for channel in samples.radars:
                pc, times = RadarPointCloud.from_file_multisweep(nusc, _sample(nusc, item["sample_token"]), channel,
                                                                 "LIDAR_TOP", nsweeps=3, min_distance=1.0)
                parts.append(np.concatenate([pc.points, times]).T)
            expected = np.concatenate(parts).astype(np.float32)
            got = item["radar_points"]
            assert got.dtype == np.float32 and got.shape == expected.shape == (len(got), 19)
            np.testing.assert_array_max_ulp(got[:, :3], expected[:, :3], maxulp=1)
            np.testing.assert_array_equal(got[:, 3:], expected[:, 3:])
            total += len(got)
        assert total > 50
    finally:
        RadarPointCloud.default_filters()


def test_one_radar_and_an_unknown_one(synth_out):
    from nuparquet.errors import UsageError

    one = Samples(synth_out, "train", lidar=False, cameras=(), boxes=False, radars=("RADAR_FRONT",), **TRAIN)
    every = Samples(synth_out, "train", lidar=False, cameras=(), boxes=False, radars="all", **TRAIN)
    front = one[3]["radar_points"]
    assert 0 < len(front) < len(every[3]["radar_points"])
    with pytest.raises(UsageError, match="RADAR_NOPE: not a radar"):
        Samples(synth_out, "train", radars=("RADAR_NOPE",), **TRAIN)
    with pytest.raises(UsageError, match="sweeps_as must be one of"):
        Samples(synth_out, "train", sweeps_as="mmdet", **TRAIN)
    with pytest.raises(UsageError, match="box_filter must be one of"):
        Samples(synth_out, "train", box_filter="valid", **TRAIN)


# --- the CAN bus vector ----------------------------------------------------------------------------------------------

def bevformer_patch(can_bus, ego2global_translation, ego2global_rotation) -> np.ndarray:
    """`CustomNuScenesDataset.get_data_info`'s patch (BEVFormer master, commit 66b65f3a,
    projects/mmdet3d_plugin/datasets/nuscenes_dataset.py), `info['ego2global_*']` being the lidar keyframe's ego
    pose as its converter writes them."""
    from nuscenes.eval.common.utils import Quaternion, quaternion_yaw

    input_dict = dict(ego2global_translation=ego2global_translation, ego2global_rotation=ego2global_rotation,
                      can_bus=can_bus)
    rotation = Quaternion(input_dict['ego2global_rotation'])
    translation = input_dict['ego2global_translation']
    can_bus = input_dict['can_bus']
    can_bus[:3] = translation
    can_bus[3:7] = rotation
    patch_angle = quaternion_yaw(rotation) / np.pi * 180
    if patch_angle < 0:
        patch_angle += 360
    can_bus[-2] = patch_angle / 180 * np.pi
    can_bus[-1] = patch_angle
    return can_bus


def bevformer_data_info_can_bus(nusc, can_bus, sample) -> np.ndarray:
    sd_rec = nusc.get("sample_data", sample["data"]["LIDAR_TOP"])
    pose_record = nusc.get("ego_pose", sd_rec["ego_pose_token"])
    return bevformer_patch(can_bus, pose_record["translation"], pose_record["rotation"])


def test_the_patch_turns_every_heading_into_0_to_360_degrees():
    """Headings all round the circle (the synthetic scenes only turn left of east), unnormalised quaternions
    included: the patch equals BEVFormer's, negative yaws moved up by 360 degrees."""
    from nuparquet.training.temporal import patched_can_bus

    rng = np.random.default_rng(1)
    yaw = np.concatenate([np.linspace(-np.pi, np.pi, 13), rng.uniform(-np.pi, np.pi, 20)])
    scale = rng.uniform(0.5, 2.0, len(yaw))
    q = np.stack([np.cos(yaw / 2), 0.01 * rng.normal(size=len(yaw)), 0.01 * rng.normal(size=len(yaw)),
                  np.sin(yaw / 2)], axis=1) * scale[:, None]
    t = rng.normal(size=(len(yaw), 3)) * 1000
    vectors = rng.normal(size=(len(yaw), 18))
    ours = patched_can_bus(vectors, t, q)
    for k in range(len(yaw)):
        expected = bevformer_patch(vectors[k].copy(), t[k].tolist(), q[k].tolist())
        np.testing.assert_array_equal(ours[k, :16], expected[:16])
        np.testing.assert_allclose(ours[k, 16:], expected[16:], rtol=1e-12, atol=1e-9)
    assert (ours[:, -1] > 180).any() and (ours[:, -1] < 180).any() and (ours[:, -1] >= 0).all()


@pytest.fixture(scope="module")
def reference_can_bus(nusc, synth_root) -> dict:
    """{sample token: the vector BEVFormer's dataset hands its pipeline}."""
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus

    clients = _can_bus_clients()
    nusc_can_bus = NuScenesCanBus(dataroot=str(synth_root))
    return {sample["token"]: bevformer_data_info_can_bus(
        nusc, clients.bevformer_get_can_bus_info(nusc, nusc_can_bus, sample), sample) for sample in nusc.sample}


def test_can_bus_equals_bevformers(synth_out, reference_can_bus):
    samples = Samples(synth_out, "train", lidar=False, cameras=(), boxes=False, can_bus=True, **TRAIN)
    without = 0
    for i in range(len(samples)):
        item = samples[i]
        expected = reference_can_bus[item["sample_token"]]
        assert item["can_bus"].dtype == np.float64 and item["can_bus"].shape == (18,)
        np.testing.assert_array_equal(item["can_bus"][:16], expected[:16])
        np.testing.assert_allclose(item["can_bus"][16:], expected[16:], rtol=1e-12, atol=1e-12)
        without += not expected[7:16].any()
    assert 0 < without < len(samples)  # the last synthetic scene has no CAN bus: BEVFormer's zeros, then the pose


# --- the queue ------------------------------------------------------------------------------------------------------

def bevformer_union2one(queue: list[dict]) -> dict:
    """`union2one`'s loop over the metas (BEVFormer master), the images left out."""
    metas_map = {}
    prev_scene_token = None
    prev_pos = None
    prev_angle = None
    for i, each in enumerate(queue):
        metas_map[i] = each['img_metas']
        if metas_map[i]['scene_token'] != prev_scene_token:
            metas_map[i]['prev_bev_exists'] = False
            prev_scene_token = metas_map[i]['scene_token']
            prev_pos = copy.deepcopy(metas_map[i]['can_bus'][:3])
            prev_angle = copy.deepcopy(metas_map[i]['can_bus'][-1])
            metas_map[i]['can_bus'][:3] = 0
            metas_map[i]['can_bus'][-1] = 0
        else:
            metas_map[i]['prev_bev_exists'] = True
            tmp_pos = copy.deepcopy(metas_map[i]['can_bus'][:3])
            tmp_angle = copy.deepcopy(metas_map[i]['can_bus'][-1])
            metas_map[i]['can_bus'][:3] -= prev_pos
            metas_map[i]['can_bus'][-1] -= prev_angle
            prev_pos = copy.deepcopy(tmp_pos)
            prev_angle = copy.deepcopy(tmp_angle)
    return metas_map


@pytest.mark.parametrize("queue_length", [2, 4])
def test_the_queue_is_bevformers_at_scene_starts_and_ends(synth_out, reference_can_bus, queue_length):
    samples = Samples(synth_out, "train", lidar=False, cameras=(), can_bus=True, queue_length=queue_length, **TRAIN)
    single = Samples(synth_out, "train", lidar=False, cameras=(), can_bus=True, **TRAIN)
    tokens, scenes = samples.sample_token.tolist(), samples.scene_token.tolist()
    starts = []
    for index in range(len(samples)):
        # prepare_test_data's queue: range(index - queue_length + 1, index + 1), each max(0, i)
        index_list = [max(0, i) for i in range(index - queue_length + 1, index + 1)]
        metas = bevformer_union2one([{"img_metas": {"scene_token": scenes[i],
                                                    "can_bus": reference_can_bus[tokens[i]].copy()}}
                                     for i in index_list])
        item = samples[index]
        frames = [*item["queue"], item]
        assert item["queue_index"].tolist() == index_list
        assert [f["sample_token"] for f in frames] == [tokens[i] for i in index_list]
        assert [f["prev_bev_exists"] for f in frames] == [metas[k]["prev_bev_exists"] for k in range(queue_length)]
        for k, frame in enumerate(frames):
            np.testing.assert_allclose(frame["can_bus"], metas[k]["can_bus"], rtol=1e-12, atol=1e-9)
            np.testing.assert_array_equal(frame["gt_bboxes_3d"], single[index_list[k]]["gt_bboxes_3d"])
            assert "queue" not in frame or frame is item
        if not item["prev_bev_exists"]:
            starts.append(index)
    # the second scene's first sample; the split's first is its own previous frame (max(0, i)), so it "exists"
    assert starts == [6] and samples[0]["queue"][0]["sample_token"] == tokens[0]
    assert samples[6]["queue"][-1]["scene_token"] != samples[6]["scene_token"]  # reaches back across the start


def test_bad_counts_are_refused(synth_out):
    from nuparquet.errors import UsageError

    for options in ({"queue_length": 0}, {"radar_sweeps": -1}, {"sweeps": -1}):
        with pytest.raises(UsageError, match="queue_length must be at least 1"):
            Samples(synth_out, "train", **options, **TRAIN)


def test_with_every_part_the_object_still_pickles_small_and_reopens(synth_out):
    import pickle

    plain = Samples(synth_out, "train", lidar=False, cameras=(), **TRAIN)
    every = Samples(synth_out, "train", lidar=False, cameras=(), radars="all", can_bus=True, bev_map=True,
                    bev_xbound=(-20.0, 20.0, 1.0), bev_ybound=(-20.0, 20.0, 1.0), queue_length=2, **TRAIN)
    data = pickle.dumps(every)
    # per sample: its 18 CAN bus values and location only (the map is opened in the worker, not carried)
    assert len(data) - len(pickle.dumps(plain)) < 300 * len(every)
    again = pickle.loads(data)
    assert again._ds is None
    expected, item = every[7], again[7]
    for key in ("radar_points", "can_bus", "gt_masks_bev", "queue_index"):
        np.testing.assert_array_equal(item[key], expected[key])
    assert item["gt_masks_bev"].shape == (6, 40, 40) and item["gt_masks_bev"].any()
    assert item["queue"][0]["sample_token"] == expected["queue"][0]["sample_token"]


def test_a_shards_queue_reads_the_rows_before_it_in_the_split(synth_out):
    samples = Samples(synth_out, "train", lidar=False, cameras=(), boxes=False, queue_length=3, **TRAIN)
    part = samples.shard(1, 2)
    first = int(part.indices[0])
    item = part[0]
    assert item["queue_index"].tolist() == [max(0, first - 2), max(0, first - 1), first]
    assert item["sample_token"] == samples.sample_token[first]


def test_can_bus_without_the_can_bus_expansion_is_refused(map_out):
    from nuparquet.errors import UsageError

    with pytest.raises(UsageError, match="has no sample_can_bus dataset, which can_bus=True reads"):
        Samples(map_out, "train", lidar=False, cameras=(), can_bus=True, **TRAIN)
