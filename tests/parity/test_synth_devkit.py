"""Devkit parity of the synthetic generator: nuscenes-devkit loads it and answers the usual questions, its camera
images show the category colour where the devkit projects each box, its lidar and radar files load in the
devkit, and every map file the devkit asserts on exists."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import NUSCENES_CHANNELS, SYNTH_VERSION


@pytest.fixture(scope="module")
def tables(synth_root) -> dict[str, list[dict]]:
    return {name: json.loads((synth_root / SYNTH_VERSION / f"{name}.json").read_text()) for name in ("map", "log")}


@pytest.fixture(scope="module")
def nusc(synth_root, devkit):
    return devkit.NuScenes(SYNTH_VERSION, dataroot=str(synth_root), verbose=False)


# -- devkit ---------------------------------------------------------------------------------------------------

def test_devkit_loads_it_and_answers_the_usual_questions(nusc):
    sample = nusc.sample[len(nusc.sample) // 2]
    assert set(sample["data"]) == NUSCENES_CHANNELS
    path, boxes, intrinsic = nusc.get_sample_data(sample["data"]["CAM_FRONT"])
    assert Path(path).is_file() and intrinsic.shape == (3, 3)
    velocities = np.array([nusc.box_velocity(a["token"]) for a in nusc.sample_annotation])
    single = np.array([a["prev"] == "" and a["next"] == "" for a in nusc.sample_annotation])
    assert np.isnan(velocities[single]).all() and np.isfinite(velocities[~single]).all()
    assert np.nanmax(np.linalg.norm(velocities[~single], axis=1)) < 25.0


def test_camera_images_show_the_category_colour_at_the_projected_centre_of_each_unoccluded_box(nusc):
    """Expected pixels come from the devkit alone: get_sample_data's boxes (interpolated for sweeps),
    view_points, and the devkit's colormap. A box counts when no nearer painted box covers its centre."""
    import cv2
    from nuscenes.utils.color_map import get_colormap
    from nuscenes.utils.geometry_utils import BoxVisibility, view_points

    colormap = get_colormap()
    checked = {"keyframe": 0, "sweep": 0}
    for sd in nusc.sample_data:
        if sd["sensor_modality"] != "camera":
            continue
        path, boxes, intrinsic = nusc.get_sample_data(sd["token"], box_vis_level=BoxVisibility.NONE)
        image = cv2.imread(path)
        assert image.shape == (900, 1600, 3)
        painted = sorted((b for b in boxes if (b.corners()[2] >= 0.1).all()), key=lambda b: b.center[2])
        hulls = [cv2.convexHull(view_points(b.corners(), intrinsic, normalize=True)[:2].T.astype(np.float32))
                 for b in painted]
        for i, box in enumerate(painted):
            u, v = view_points(box.center[:, None], intrinsic, normalize=True)[:2, 0]
            size_px = np.ptp(hulls[i][:, 0, :], axis=0)
            if not (8 <= u < 1592 and 8 <= v < 892) or size_px.min() < 30:
                continue
            if any(cv2.pointPolygonTest(hull, (float(u), float(v)), True) > -4 for hull in hulls[:i]):
                continue  # a nearer box is painted over this one's centre
            patch = image[int(v) - 2:int(v) + 3, int(u) - 2:int(u) + 3].reshape(-1, 3).astype(int)
            rgb = np.median(patch, axis=0)[::-1]
            assert np.abs(rgb - colormap[box.name]).max() <= 24, (sd["filename"], box.name, rgb)
            checked["keyframe" if sd["is_key_frame"] else "sweep"] += 1
    assert checked["keyframe"] >= 100 and checked["sweep"] >= 400, checked


def test_lidar_files_are_float32_rows_of_five_with_num_lidar_pts_on_each_box(nusc, synth_root):
    from nuscenes.utils.data_classes import LidarPointCloud
    from nuscenes.utils.geometry_utils import points_in_box

    files = sorted((synth_root / "sweeps" / "LIDAR_TOP").glob("*.pcd.bin"))
    assert files
    for path in files:
        scan = np.fromfile(path, dtype=np.float32)
        assert scan.size % 5 == 0 and scan.size > 5 * 1000
        points = scan.reshape(-1, 5)
        assert np.isfinite(points).all()
        assert set(np.unique(points[:, 4])) <= set(range(32))  # ring index
    matching = total = 0
    for sample in nusc.sample:
        path, boxes, _ = nusc.get_sample_data(sample["data"]["LIDAR_TOP"])
        cloud = LidarPointCloud.from_file(path)
        for box in boxes:
            total += 1
            matching += points_in_box(box, cloud.points[:3]).sum() == nusc.get("sample_annotation", box.token)[
                "num_lidar_pts"]
    assert matching >= 0.95 * total  # exact except where two boxes overlap


def test_radar_files_load_in_the_devkit(nusc):
    from nuscenes.utils.data_classes import RadarPointCloud

    for sample in nusc.sample[:3]:
        for channel in ("RADAR_FRONT", "RADAR_BACK_LEFT"):
            cloud = RadarPointCloud.from_file(nusc.get_sample_data_path(sample["data"][channel]))
            assert cloud.points.shape[0] == 18 and cloud.points.shape[1] >= 1


def test_every_map_file_exists(synth_root, tables):
    import cv2

    for record in tables["map"]:
        assert cv2.imread(str(synth_root / record["filename"])) is not None
    assert sorted(t for m in tables["map"] for t in m["log_tokens"]) == sorted(log["token"] for log in tables["log"])


