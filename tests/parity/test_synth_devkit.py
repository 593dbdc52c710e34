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




def test_lidarseg_labels_are_the_class_of_the_devkit_box_each_point_lies_in(nusc, synth_root):
    """Each keyframe's lidarseg label of a point is the lidarseg index of the category of the devkit box it lies in
    (`points_in_box` on `get_sample_data`'s boxes in the lidar frame), and flat.driveable_surface for a point in
    no box (the generator's ground returns), point for point."""
    from nuscenes.utils.data_classes import LidarPointCloud
    from nuscenes.utils.geometry_utils import points_in_box

    index = nusc.lidarseg_name2idx_mapping
    in_box = on_ground = 0
    for sample in nusc.sample:
        token = sample["data"]["LIDAR_TOP"]
        path, boxes, _ = nusc.get_sample_data(token)
        points = LidarPointCloud.from_file(path).points[:3]
        labels = np.fromfile(synth_root / nusc.get("lidarseg", token)["filename"], dtype=np.uint8)
        assert labels.shape == (points.shape[1],)
        inside = np.array([points_in_box(box, points) for box in boxes]).reshape(len(boxes), -1)
        assert inside.sum(axis=0).max() <= 1  # the generator's boxes do not overlap: one class per point
        expected = np.full(points.shape[1], index["flat.driveable_surface"])
        for box, mask in zip(boxes, inside):
            expected[mask] = index[box.name]
        np.testing.assert_array_equal(labels, expected)
        in_box += int(inside.any(axis=0).sum())
        on_ground += int((~inside.any(axis=0)).sum())
    assert in_box > 10_000 and on_ground > 10_000


def test_camera_images_paint_each_box_out_to_the_corners_the_devkit_projects(nusc):
    """The painted box is the convex hull of the devkit's eight projected corners (`Box.corners()`, view_points):
    inside it, three quarters of the way from the centre to each corner of the hull, the pixel has the category's
    colour, wherever no nearer box is painted within 4 px (keyframes; expectations from the devkit alone)."""
    import cv2
    from nuscenes.utils.color_map import get_colormap
    from nuscenes.utils.geometry_utils import BoxVisibility, view_points

    colormap = get_colormap()
    checked = 0
    for sd in nusc.sample_data:
        if sd["sensor_modality"] != "camera" or not sd["is_key_frame"]:
            continue
        path, boxes, intrinsic = nusc.get_sample_data(sd["token"], box_vis_level=BoxVisibility.NONE)
        image = cv2.imread(path)
        painted = sorted((b for b in boxes if (b.corners()[2] >= 0.1).all()), key=lambda b: b.center[2])
        hulls = [cv2.convexHull(view_points(b.corners(), intrinsic, normalize=True)[:2].T.astype(np.float32))
                 for b in painted]
        for i, box in enumerate(painted):
            hull = hulls[i][:, 0, :]
            if np.ptp(hull, axis=0).min() < 40:
                continue
            centre = hull.mean(axis=0)
            for corner in hull:
                u, v = centre + 0.75 * (corner - centre)
                if not (8 <= u < 1592 and 8 <= v < 892) or cv2.pointPolygonTest(hulls[i], (float(u), float(v)),
                                                                                 True) < 4:
                    continue
                if any(cv2.pointPolygonTest(h, (float(u), float(v)), True) > -4 for h in hulls[:i]):
                    continue  # a nearer box is painted here
                patch = image[int(v) - 2:int(v) + 3, int(u) - 2:int(u) + 3].reshape(-1, 3).astype(int)
                rgb = np.median(patch, axis=0)[::-1]
                assert np.abs(rgb - colormap[box.name]).max() <= 24, (sd["filename"], box.name, (u, v), rgb)
                checked += 1
    assert checked >= 300, checked
