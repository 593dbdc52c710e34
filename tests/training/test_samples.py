"""`Samples` against independent computations: mmdetection3d v1.4.0's `LoadPointsFromMultiSweeps` restated line
for line below, fed by the v2 info pickle `build_index` writes (equal to mmdetection3d's: tests/index/) and the
lidar files read with np.fromfile; boxes against the infos' `instances`; images against cv2.imread of the files;
lidar2img against the infos' cam2img and lidar2cam."""

from __future__ import annotations

import os
import pickle

import cv2
import numpy as np
import pytest

from nuparquet.errors import UsageError
from nuparquet.index import IndexOptions, build_index
from nuparquet.index.labels import CLASSES
from nuparquet.training.samples import Samples

SWEEPS = 3


@pytest.fixture(scope="session")
def synth_v2_infos(synth_out, tmp_path_factory) -> dict:
    """{sample token: v2 data_list entry} of the train split (both synth scenes are train), SWEEPS sweeps."""
    out = tmp_path_factory.mktemp("training-infos")
    build_index(synth_out, str(out), IndexOptions(version="v1.0-trainval", max_sweeps=SWEEPS, parquet=False))
    infos = pickle.loads((out / "nuscenes_infos_train.pkl").read_bytes())
    return {entry["token"]: entry for entry in infos["data_list"]}


@pytest.fixture(scope="session")
def synth_samples(synth_out) -> Samples:
    return Samples(synth_out, "train", sweeps=SWEEPS, version="v1.0-trainval")


# --- mmdetection3d v1.4.0, mmdet3d/datasets/transforms/loading.py, restated over numpy -------------------------------

def _load_points(path: str) -> np.ndarray:  # LoadPointsFromFile._load_points (load_dim=5)
    return np.fromfile(path, dtype=np.float32)


def _remove_close(points: np.ndarray, radius: float = 1.0) -> np.ndarray:  # LoadPointsFromMultiSweeps._remove_close
    x_filt = np.abs(points[:, 0]) < radius
    y_filt = np.abs(points[:, 1]) < radius
    not_close = np.logical_not(np.logical_and(x_filt, y_filt))
    return points[not_close]


def load_points_from_multi_sweeps(results: dict, sweeps_num: int = SWEEPS, load_dim: int = 5) -> np.ndarray:
    """LoadPointsFromMultiSweeps(sweeps_num, use_dim=[0, 1, 2, 3, 4], pad_empty_sweeps=True, remove_close=True,
    test_mode=True).transform, `results['points']` as LoadPointsFromFile(load_dim=5, use_dim=5) left it."""
    points = results["points"]
    points[:, 4] = 0
    sweep_points_list = [points]
    ts = results["timestamp"]
    if "lidar_sweeps" not in results:
        for i in range(sweeps_num):
            sweep_points_list.append(_remove_close(points))
    else:
        if len(results["lidar_sweeps"]) <= sweeps_num:
            choices = np.arange(len(results["lidar_sweeps"]))
        else:
            choices = np.arange(sweeps_num)
        for idx in choices:
            sweep = results["lidar_sweeps"][idx]
            points_sweep = _load_points(sweep["lidar_points"]["lidar_path"])
            points_sweep = np.copy(points_sweep).reshape(-1, load_dim)
            points_sweep = _remove_close(points_sweep)
            sweep_ts = sweep["timestamp"]
            lidar2sensor = np.array(sweep["lidar_points"]["lidar2sensor"])
            points_sweep[:, :3] = points_sweep[:, :3] @ lidar2sensor[:3, :3]
            points_sweep[:, :3] -= lidar2sensor[:3, 3]
            points_sweep[:, 4] = ts - sweep_ts
            sweep_points_list.append(points_sweep)
    points = np.concatenate(sweep_points_list)
    return points[:, [0, 1, 2, 3, 4]]


def _mmdet3d_points(entry: dict, root) -> np.ndarray:
    results = {"timestamp": entry["timestamp"],
               "points": _load_points(str(root / "samples" / "LIDAR_TOP" / entry["lidar_points"]["lidar_path"]))
               .reshape(-1, 5)}
    if "lidar_sweeps" in entry:  # Det3DDataset.parse_data_info joins the sweeps' prefix; ours: the dataroot
        results["lidar_sweeps"] = [
            {**s, "lidar_points": {**s["lidar_points"], "lidar_path": str(
                root / os.path.relpath(s["lidar_points"]["lidar_path"], "./data/nuscenes"))}}
            for s in entry["lidar_sweeps"]]
    return load_points_from_multi_sweeps(results)


# --- the tests --------------------------------------------------------------------------------------------------------

def test_order_is_scene_then_timestamp_and_covers_the_split(synth_samples, synth_v2_infos, synth_out):
    from nuparquet.dataset import open_dataset

    scenes = open_dataset(synth_out).scan("tables/scene").select("token").collect()["token"].to_list()
    keys = [(scenes.index(synth_samples.scene_token[i]), synth_samples.timestamp_us[i])
            for i in range(len(synth_samples))]
    assert keys == sorted(keys) and len(set(keys)) == len(keys)
    assert sorted(synth_samples.sample_token.tolist()) == sorted(synth_v2_infos)
    assert len(synth_samples) == len(synth_v2_infos)


def test_points_equal_mmdet3d_load_points_from_multi_sweeps(synth_samples, synth_v2_infos, synth_root):
    seen_sweeps = set()
    for i in range(len(synth_samples)):
        item = synth_samples[i]
        entry = synth_v2_infos[item["sample_token"]]
        expected = _mmdet3d_points(entry, synth_root)
        assert item["points"].dtype == np.float32 and item["points"].shape[1] == 5
        np.testing.assert_array_equal(item["points"], expected)
        assert item["lidar_sweeps"] == len(entry.get("lidar_sweeps", []))
        seen_sweeps.add(item["lidar_sweeps"])
    assert 0 in seen_sweeps and SWEEPS in seen_sweeps  # the padded first sample and full sweep lists both checked


def test_boxes_equal_the_infos_instances(synth_out, synth_v2_infos):
    for box_filter, keep in (("valid_flag", lambda a: a["bbox_3d_isvalid"]),
                             ("num_lidar_pts", lambda a: a["num_lidar_pts"] > 0), (None, lambda a: True)):
        samples = Samples(synth_out, "train", sweeps=0, cameras=(), lidar=False, box_filter=box_filter,
                          version="v1.0-trainval")
        for i in range(len(samples)):
            item = samples[i]
            kept = [a for a in synth_v2_infos[item["sample_token"]]["instances"] if keep(a)]
            assert set(item) == {"sample_token", "timestamp_us", "scene_token", "gt_bboxes_3d", "gt_labels_3d",
                                 "num_lidar_pts"}
            boxes = np.array([a["bbox_3d"] for a in kept], dtype=np.float32).reshape(-1, 7)
            velocity = np.array([a["velocity"] for a in kept], dtype=np.float64).reshape(-1, 2)
            velocity[np.isnan(velocity[:, 0])] = 0.0
            boxes[:, 2] -= boxes[:, 5] / 2  # LiDARInstance3DBoxes(origin=(0.5, 0.5, 0.5)): bottom centre
            np.testing.assert_array_equal(item["gt_bboxes_3d"][:, :7], boxes)
            np.testing.assert_array_equal(item["gt_bboxes_3d"][:, 7:], velocity.astype(np.float32))
            assert item["gt_labels_3d"].tolist() == [a["bbox_label_3d"] for a in kept]
            assert item["num_lidar_pts"].tolist() == [a["num_lidar_pts"] for a in kept]


def test_labels_follow_the_class_list(synth_out, synth_v2_infos):
    classes = ("pedestrian", "car")
    samples = Samples(synth_out, "train", sweeps=0, cameras=(), lidar=False, classes=classes, velocity=False,
                      box_filter=None, version="v1.0-trainval")
    labels = []
    for i in range(len(samples)):
        item = samples[i]
        assert item["gt_bboxes_3d"].shape[1] == 7
        expected = [classes.index(CLASSES[a["bbox_label_3d"]]) if a["bbox_label_3d"] >= 0
                    and CLASSES[a["bbox_label_3d"]] in classes else -1
                    for a in synth_v2_infos[item["sample_token"]]["instances"]]
        assert item["gt_labels_3d"].tolist() == expected
        labels += expected
    assert -1 in labels and max(labels) >= 0


def test_images_and_camera_matrices_equal_imread_and_the_infos(synth_out, synth_v2_infos, synth_root):
    samples = Samples(synth_out, "train", sweeps=0, lidar=False, boxes=False, version="v1.0-trainval")
    for i in (0, len(samples) - 1):
        item = samples[i]
        images = synth_v2_infos[item["sample_token"]]["images"]
        assert list(images) == list(samples.cameras)
        for k, (channel, cam) in enumerate(images.items()):
            expected = cv2.imread(str(synth_root / "samples" / channel / cam["img_path"]))  # BGR, as mmcv
            np.testing.assert_array_equal(item["img"][k], expected)
            # mmdetection3d's projects/BEVFusion/bevfusion/loading.py, BEVLoadMultiViewImageFromFiles.transform
            lidar2cam_array = np.array(cam["lidar2cam"]).astype(np.float32)
            lidar2cam_rot = lidar2cam_array[:3, :3]
            lidar2cam_trans = lidar2cam_array[:3, 3:4]
            camera2lidar = np.eye(4)
            camera2lidar[:3, :3] = lidar2cam_rot.T
            camera2lidar[:3, 3:4] = -1 * np.matmul(lidar2cam_rot.T, lidar2cam_trans.reshape(3, 1))
            cam2img_array = np.eye(4).astype(np.float32)
            cam2img_array[:3, :3] = np.array(cam["cam2img"]).astype(np.float32)
            for key, expected_matrix in (("cam2img", cam2img_array), ("lidar2cam", np.array(cam["lidar2cam"])),
                                         ("cam2lidar", camera2lidar), ("lidar2img", cam2img_array @ lidar2cam_array)):
                assert item[key].dtype == expected_matrix.dtype, key
                np.testing.assert_array_equal(item[key][k], expected_matrix)
            # and the lidar frame maps through lidar2img to the pixels cam2img gives the camera frame
            point = np.array([3.0, 1.0, 0.5, 1.0])
            np.testing.assert_allclose(item["lidar2img"][k] @ point, cam2img_array @ (np.array(cam["lidar2cam"]) @ point),
                                       rtol=1e-5)
        assert item["img"].dtype == np.uint8 and item["img"].shape[-1] == 3
    rgb = Samples(synth_out, "train", sweeps=0, lidar=False, boxes=False, version="v1.0-trainval", rgb=True)[0]
    np.testing.assert_array_equal(rgb["img"], samples[0]["img"][..., ::-1])


def test_the_object_pickles_small_and_reopens_lazily(synth_samples):
    data = pickle.dumps(synth_samples)
    # per sample: its tokens, file names, matrices and ~36 boxes (SWEEPS sweeps, 6 cameras), nothing of the tables
    # (measured 4.0 kB a sample here; ~4.8 kB with 10 sweeps)
    assert len(data) < 4_500 * len(synth_samples)
    # fixed-width arrays only: a forked worker's reads touch no Python object (no copy-on-write growth)
    arrays = [v for v in vars(synth_samples).values() if isinstance(v, np.ndarray)]
    assert len(arrays) > 15 and all(a.dtype != object for a in arrays)
    again = pickle.loads(data)
    assert again._ds is None
    np.testing.assert_array_equal(again[3]["points"], synth_samples[3]["points"])
    assert again._ds is not None


def test_a_split_the_version_lacks_is_refused(synth_out):
    from nuparquet.errors import UsageError

    with pytest.raises(UsageError, match="no test split"):
        Samples(synth_out, "test", version="v1.0-trainval")


def test_close_points_leave_the_sweeps_and_the_pads_but_not_the_keyframe(synth_samples, monkeypatch):
    """A point 0.3 m from the lidar added to every reading: LoadPointsFromMultiSweeps keeps the keyframe's (it
    never filters the keyframe) and drops the sweeps' and the padding copies' (remove_close, radius 1 m)."""
    read = Samples._read_lidar
    close = np.array([[0.3, -0.2, 0.5, 7.0, 1.0]], dtype=np.float32)
    monkeypatch.setattr(Samples, "_read_lidar", lambda self, token, filename: np.concatenate(
        [read(self, token, filename), close]))
    for i in (0, len(synth_samples) - 1):  # the first has no sweeps (padded), the last SWEEPS
        points = synth_samples[i]["points"]
        near = points[(np.abs(points[:, 0]) < 1.0) & (np.abs(points[:, 1]) < 1.0)]
        np.testing.assert_array_equal(near, np.array([[0.3, -0.2, 0.5, 7.0, 0.0]], dtype=np.float32))


@pytest.mark.parametrize("method", ["spawn", "fork"])
def test_a_worker_process_reads_the_same_sample(synth_samples, method):
    """A DataLoader worker's view: the object sent to a spawned process opens the dataset there; a forked one
    inherits it after polars has run here (its thread pool is gone in the child), and reads the default parts with
    pyarrow and numpy alone. A hang would be a timeout, not a stuck suite."""
    import multiprocessing
    import operator

    expected = synth_samples[5]
    with multiprocessing.get_context(method).Pool(1) as pool:
        item = pool.apply_async(operator.getitem, (synth_samples, 5)).get(timeout=120)
    assert sorted(item) == sorted(expected) and item["sample_token"] == expected["sample_token"]
    for key in ("points", "gt_bboxes_3d", "gt_labels_3d", "img", "lidar2img"):
        np.testing.assert_array_equal(item[key], expected[key])


def test_a_forked_worker_asked_for_a_polars_part_says_to_spawn(synth_out):
    """Radar points compute with polars per item: in a forked worker that would hang, so it is refused, naming
    the part and the spawn context."""
    import multiprocessing
    import operator

    samples = Samples(synth_out, "train", version="v1.0-trainval", radars="all", cameras=None)
    samples[0]  # the parent reads one (polars' pool started) before forking, as a DataLoader's user may
    with multiprocessing.get_context("fork").Pool(1) as pool:
        with pytest.raises(UsageError, match="Samples with radars cannot be read in a forked worker.*"
                                             "multiprocessing_context='spawn'"):
            pool.apply_async(operator.getitem, (samples, 0)).get(timeout=120)
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        item = pool.apply_async(operator.getitem, (samples, 0)).get(timeout=120)
    np.testing.assert_array_equal(item["radar_points"], samples[0]["radar_points"])
