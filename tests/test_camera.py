"""The batch camera model (`nuparquet.geometry.Cameras`) against hand computation and OpenCV's resize."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from nuparquet import geometry
from nuparquet.geometry import Cameras, scale_intrinsic, scale_pixels

K = np.array([[1000.0, 0.0, 800.0], [0.0, 1000.0, 450.0], [0.0, 0.0, 1.0]])
# Camera axes (x right, y down, z forward) in the ego frame (x forward, y left, z up), 1.5 m above the origin.
EGO_FROM_CAMERA = geometry.rigid_transforms([0.0, 0.0, 1.5], [0.5, -0.5, 0.5, -0.5])


def two_cameras() -> Cameras:
    """Camera 0: ego at the origin facing +x. Camera 1: ego at (10, 5) facing +y (turned 90 degrees left)."""
    global_from_ego = np.stack([
        geometry.rigid_transforms([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]),
        geometry.rigid_transforms([10.0, 5.0, 0.0], [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)]),
    ])
    return Cameras.from_poses(global_from_ego, np.stack([EGO_FROM_CAMERA] * 2), np.stack([K, K]),
                              [[1600, 900], [1600, 900]])


def test_points_move_into_each_camera_with_its_own_pose():
    cameras = two_cameras()
    # 20 m ahead of each ego vehicle, on the ground: 1.5 m below the camera, straight ahead.
    points = np.array([[20.0, 0.0, 0.0], [10.0, 25.0, 0.0]])
    np.testing.assert_allclose(cameras.to_camera(points), [[0.0, 1.5, 20.0], [0.0, 1.5, 20.0]], atol=1e-12)
    np.testing.assert_allclose(geometry.transform_points(cameras.camera_from_global, points),
                               [[0.0, 1.5, 20.0], [0.0, 1.5, 20.0]], atol=1e-12)
    uv, depth = cameras.project(cameras.to_camera(points))
    # u = cx, v = cy + f * 1.5 / 20 = 450 + 75.
    np.testing.assert_allclose(uv, [[800.0, 525.0], [800.0, 525.0]], atol=1e-9)
    np.testing.assert_allclose(depth, [20.0, 20.0])


def test_take_picks_and_repeats_cameras():
    cameras = two_cameras()
    picked = cameras.take(np.array([1, 1, 0]))
    assert len(picked) == 3
    np.testing.assert_array_equal(picked.ego_from_global[2], cameras.ego_from_global[0])
    np.testing.assert_array_equal(picked.ego_from_global[:2], cameras.ego_from_global[[1, 1]])


def test_resized_camera_projects_where_cv2_resize_moves_the_pixel():
    # A 2x2 white block centred at (1000.5, 600.5) in a 1600x900 image, downscaled to 800x450 by area.
    image = np.zeros((900, 1600), np.uint8)
    image[600:602, 1000:1002] = 255
    small = cv2.resize(image, (800, 450), interpolation=cv2.INTER_AREA)
    v, u = np.argwhere(small == 255)[0]
    cameras = two_cameras().take([0])
    point_camera = cameras.unproject(np.array([[[1000.5, 600.5]]]), np.array([[12.0]]))  # depth 12 m
    # by hand: x = (u - cx) z / f, y = (v - cy) z / f, z the depth
    np.testing.assert_allclose(point_camera[0, 0], [200.5 * 12 / 1000, 150.5 * 12 / 1000, 12.0], atol=1e-12)
    uv, _ = cameras.resized_to((800, 450)).project(point_camera)
    np.testing.assert_allclose(uv[0, 0], [u, v], atol=1e-9)
    np.testing.assert_allclose(scale_pixels([[1000.5, 600.5]], 0.5)[0], [u, v])


def test_resizing_equals_scaling_the_full_size_pixels_per_axis():
    cameras = two_cameras()
    points = np.random.default_rng(0).uniform([-5, -3, 2], [5, 3, 40], (2, 50, 3))
    full, _ = cameras.project(points)
    scale = np.array([[0.25, 0.2], [0.5, 0.5]])  # per camera, per axis
    resized, _ = cameras.resized(scale).project(points)
    np.testing.assert_allclose(resized, scale_pixels(full, scale[:, None, :]), atol=1e-9)
    np.testing.assert_allclose(cameras.resized(scale).size_px, [[400.0, 180.0], [800.0, 450.0]])
    np.testing.assert_allclose(scale_intrinsic(K, 0.5), [[500.0, 0, 399.75], [0, 500.0, 224.75], [0, 0, 1]])


@pytest.mark.parametrize("margin_px", [0.0, 1.0])
def test_in_image_keeps_the_full_size_region_after_resizing(margin_px):
    cameras = two_cameras().take([0])
    # Pixels just inside and just outside the devkit's open interval margin < u < W - margin, on both axes.
    eps = 1e-6
    full = np.array([[[margin_px + eps, 450.0], [margin_px - eps, 450.0], [1600.0 - margin_px - eps, 450.0],
                      [1600.0 - margin_px + eps, 450.0], [800.0, margin_px + eps], [800.0, 900.0 - margin_px + eps]]])
    expected = [True, False, True, False, True, False]
    assert cameras.in_image(full, margin_px).tolist() == [expected]
    small = cameras.resized_to((400, 225))
    assert small.in_image(scale_pixels(full, 0.25), margin_px).tolist() == [expected]


def test_clip_segments_cuts_at_the_near_plane_and_projects_with_each_cameras_intrinsics():
    cameras = two_cameras().resized(np.array([[1.0, 1.0], [0.5, 0.5]]))
    # Per camera one segment from 2 m in front to 1 m behind, and one entirely behind.
    segments = np.array([[[0.0, 0.0, 2.0], [0.0, 0.0, -1.0]], [[1.0, 0.0, -1.0], [1.0, 0.0, -2.0]]])
    clipped, keep = cameras.clip_segments(np.stack([segments, segments]), near_m=0.1)
    assert keep.tolist() == [[True, False], [True, False]]
    assert np.isnan(clipped[:, 1]).all()
    # The far end lands on z = 0.1 on the line x = y = 0: the principal point, of each camera.
    np.testing.assert_allclose(clipped[0, 0], [[800.0, 450.0], [800.0, 450.0]], atol=1e-9)
    np.testing.assert_allclose(clipped[1, 0], [[399.75, 224.75], [399.75, 224.75]], atol=1e-9)


def test_rotation_to_camera_turns_a_global_orientation_into_each_cameras_axes():
    """A box facing global +y (yaw 90 degrees), worked out by hand: camera 1's ego faces +y, so the box's forward
    axis is the camera's forward (z), its left (global -x) the camera's -x, its up the camera's -y; camera 0's ego
    faces +x, so the box's forward is the ego's left (camera -x) and its left the ego's back (camera -z)."""
    yaw_90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    ours = two_cameras().rotation_to_camera(yaw_90)
    assert ours.shape == (2, 3, 3)
    np.testing.assert_allclose(ours[1], [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(ours[0], [[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]], atol=1e-12)
