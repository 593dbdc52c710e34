"""nuparquet.geometry's contract beyond the devkit comparisons: errors that name the argument, batch shapes
(one transform or box, stacks of several dimensions, broadcasting one pose against many), view matrix limits,
the default projection, and silent division at depth 0. Expectations are plain numpy loops."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from nuparquet import geometry

IDENTITY_Q = [1.0, 0.0, 0.0, 0.0]


def about_z(yaw: float) -> list[float]:
    return [float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2))]


@pytest.mark.parametrize("call, name", [
    (lambda: geometry.rigid_transforms([1.0, 2.0], IDENTITY_Q), "translation_m"),
    (lambda: geometry.invert_rigid(np.eye(3)), "X_from_Y"),
    (lambda: geometry.transform_points(np.eye(3), [1.0, 2.0, 3.0]), "X_from_Y"),
    (lambda: geometry.transform_points(np.eye(4), [1.0, 2.0]), "points_Y"),
    (lambda: geometry.box_corners([1.0, 2.0], [1.0, 1.0, 1.0], IDENTITY_Q), "translation_m"),
    (lambda: geometry.box_corners([1.0, 2.0, 3.0], [1.0, 1.0], IDENTITY_Q), "size_wlh_m"),
    (lambda: geometry.view_points([1.0, 2.0], np.eye(3)), "points"),
    (lambda: geometry.quaternion_slerp([IDENTITY_Q], [[1.0, 0.0, 0.0]], 0.5), "q1_wxyz"),
    (lambda: geometry.quaternion_slerp([[1.0, 0.0, 0.0]], [IDENTITY_Q], 0.5), "q0_wxyz"),
])
def test_wrong_shapes_are_errors_naming_the_argument(call, name):
    with pytest.raises(ValueError, match=rf"^{name} must have shape"):
        call()


def test_points_that_fit_no_stack_of_transforms_say_what_fits():
    with pytest.raises(ValueError, match=r"do not fit transforms of shape \(2,\) \+ \(4, 4\): expected \(B\.\.\., 3\)"):
        geometry.transform_points(np.tile(np.eye(4), (2, 1, 1)), np.zeros((2, 5, 7, 3)))


def test_one_pose_broadcasts_against_many_and_many_against_one():
    translations = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]])
    rotations = np.array([about_z(0.1), about_z(0.7), about_z(-1.2)])
    many_t = geometry.rigid_transforms(translations, IDENTITY_Q)
    many_q = geometry.rigid_transforms([1.0, 2.0, 3.0], rotations)
    assert many_t.shape == many_q.shape == (3, 4, 4)
    for i in range(3):
        np.testing.assert_array_equal(many_t[i], geometry.rigid_transforms(translations[i], IDENTITY_Q))
        np.testing.assert_array_equal(many_q[i], geometry.rigid_transforms([1.0, 2.0, 3.0], rotations[i]))
    grid = geometry.rigid_transforms(translations[:, None, :], rotations[None, :, :])  # (3, 1) x (1, 3)
    assert grid.shape == (3, 3, 4, 4)
    np.testing.assert_array_equal(grid[2, 1], geometry.rigid_transforms(translations[2], rotations[1]))


@pytest.mark.parametrize("batch", [(), (4,), (2, 3)])
def test_box_corners_keep_the_batch_shape(batch):
    rng = np.random.default_rng(1)
    centres = rng.uniform(-5, 5, batch + (3,))
    sizes = rng.uniform(0.5, 4, batch + (3,))
    rotations = np.broadcast_to(about_z(0.4), batch + (4,))
    corners = geometry.box_corners(centres, sizes, rotations)
    assert corners.shape == batch + (8, 3)
    flat = geometry.box_corners(centres.reshape(-1, 3), sizes.reshape(-1, 3), rotations.reshape(-1, 4))
    np.testing.assert_array_equal(corners.reshape(-1, 8, 3), flat)
    ints = geometry.box_corners([1, 2, 3], [2, 4, 2], [1, 0, 0, 0])  # integer input: float results
    np.testing.assert_array_equal(ints, geometry.box_corners([1.0, 2.0, 3.0], [2.0, 4.0, 2.0], IDENTITY_Q))


def test_view_points_projects_by_default_and_refuses_views_over_4x4():
    intrinsic = np.array([[1000.0, 0.0, 800.0], [0.0, 1000.0, 450.0], [0.0, 0.0, 1.0]])
    points = np.array([[1.0, -2.0, 10.0], [0.5, 0.5, 2.0]])
    expected = points @ intrinsic.T
    np.testing.assert_allclose(geometry.view_points(points, intrinsic), expected / expected[:, 2:3], rtol=1e-15)
    for shape in ((5, 4), (4, 5), (5, 5)):
        with pytest.raises(ValueError, match=rf"at most 4x4, got \({shape[0]}, {shape[1]}\)"):
            geometry.view_points(points, np.eye(*shape))
    with pytest.raises(ValueError, match=r"at most 4x4, got \(5, 4\)$"):  # a stack: the view's own shape
        geometry.view_points(points[:1], np.tile(np.eye(5, 4), (1, 1, 1)))


def test_view_points_with_one_point_per_view_of_a_stack():
    rng = np.random.default_rng(2)
    views = np.tile(np.eye(4), (5, 1, 1))
    views[:, :3, :3] = rng.uniform(0.5, 2.0, (5, 3, 3))
    views[:, :3, 3] = rng.uniform(-1, 1, (5, 3))
    points = rng.uniform([-1, -1, 2], [1, 1, 5], (5, 3))
    got = geometry.view_points(points, views, normalize=False)
    assert got.shape == (5, 3)
    for i in range(5):
        np.testing.assert_allclose(got[i], views[i, :3, :3] @ points[i] + views[i, :3, 3], rtol=1e-14)


def test_points_at_depth_zero_project_to_inf_and_nan_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        projected = geometry.view_points(np.array([[1.0, 1.0, 0.0], [0.0, 0.0, 0.0]]), np.eye(3), normalize=True)
    assert np.isinf(projected[0, :2]).all() and np.isnan(projected[1]).all()


def test_rowwise_dots_and_norms_round_as_np_dot_and_np_linalg_norm_of_one_vector():
    """The devkit's center_distance / velocity_l2 and pyquaternion's q . q are np.dot / np.linalg.norm of one small
    vector (BLAS ddot, whose rounding the CPU's kernel decides): ours must give the same bits on this machine, for
    2- and 4-vectors, contiguous or strided, with NaN, and broadcast against one vector."""
    from nuparquet.geometry.dots import rowwise_dot, rowwise_norm

    rng = np.random.default_rng(35)
    for k in (2, 4):
        a = rng.normal(size=(3000, k)) * rng.uniform(1e-3, 2e3, (3000, 1))
        b = rng.normal(size=(3000, 2 * k))[:, ::2]  # strided rows
        a[7, 0] = np.nan
        expected_dot = np.array([np.dot(x, y) for x, y in zip(a, b)])
        expected_norm = np.array([np.linalg.norm(x) for x in a])
        np.testing.assert_array_equal(rowwise_dot(a, b), expected_dot)
        np.testing.assert_array_equal(rowwise_norm(a), expected_norm)
        np.testing.assert_array_equal(rowwise_dot(a, b[0]), [np.dot(x, b[0]) for x in a])
        assert rowwise_dot(a.reshape(3, 1000, k), b.reshape(3, 1000, k)).shape == (3, 1000)


def test_a_box_pair_at_the_cameras_centre_projects_without_warnings():
    """A box with a corner on the camera's centre (that corner projects as 0/0, its neighbours at depth 0 as x/0)
    is a pair outside the image, and the projection warns about nothing (those divisions are expected, masked)."""
    from nuparquet.geometry import box_half_axes
    from nuparquet.geometry.box_projection import project_pairs

    cameras = geometry.Cameras(np.eye(4)[None], np.eye(4)[None], np.array([[[1000.0, 0, 800], [0, 1000.0, 450],
                                                                          [0, 0, 1]]]), np.array([[1600.0, 900.0]]),
                               np.ones((1, 2)))
    half_axes = box_half_axes(np.array([[2.0, 2.0, 2.0]]), np.array([IDENTITY_Q]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = project_pairs(cameras, [0], [[1.0, 1.0, 1.0]], half_axes, [0], kernel="numpy")
    assert out.in_front.tolist() == [False] and out.visible.tolist() == [False]
    assert np.isnan(out.corners_px[0]).any()  # the corner on the centre: 0/0, as the devkit's view_points gives


def test_cuboids_of_array_likes_keep_one_row_per_box():
    from nuparquet.geometry.cuboids import Cuboids

    boxes = Cuboids.of([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], [[2.0, 4.0, 1.5]] * 2, [IDENTITY_Q, about_z(0.5)])
    assert boxes.translation_m.shape == (2, 3) and boxes.size_wlh_m.shape == (2, 3)
    assert boxes.rotation_wxyz.shape == (2, 4) and boxes.rotation_wxyz.dtype == np.float64
    np.testing.assert_array_equal(boxes.rotation_wxyz[1], about_z(0.5))
    one = Cuboids.of([1.0, 2.0, 3.0], [2.0, 4.0, 1.5], IDENTITY_Q, at="ego")
    assert one.rotation_wxyz.shape == (1, 4) and one.at == "ego"
