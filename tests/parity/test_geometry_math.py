"""nuparquet.geometry against pyquaternion and the devkit's Box / view_points on seeded random inputs."""

from __future__ import annotations

import numpy as np
import pytest

from nuparquet import geometry
from nuparquet.geometry import quaternions

from pyquaternion import Quaternion  # a devkit dependency: missing is a failure, never a skip

N = 500


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20181008)


def random_quaternions(rng: np.random.Generator, n: int = N) -> np.ndarray:
    """(n, 4) quaternions of random norm in [0.5, 2]: pyquaternion normalises, so must we."""
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True) * rng.uniform(0.5, 2.0, size=(n, 1))


def random_poses(rng: np.random.Generator, n: int = N) -> tuple[np.ndarray, np.ndarray]:
    """Translations of nuScenes global-frame magnitude (~1e3 m) and unit quaternions."""
    q = rng.normal(size=(n, 4))
    return rng.uniform(-2000.0, 2000.0, size=(n, 3)), q / np.linalg.norm(q, axis=1, keepdims=True)


def test_rotation_matrices_equal_pyquaternion(rng):
    q = random_quaternions(rng)
    expected = np.stack([Quaternion(row).rotation_matrix for row in q])
    np.testing.assert_allclose(quaternions.rotation_matrices(q), expected, rtol=0, atol=1e-12)


def test_rotation_matrices_are_orthonormal_with_determinant_one(rng):
    rotation = quaternions.rotation_matrices(random_quaternions(rng))
    identity = np.broadcast_to(np.eye(3), rotation.shape)
    np.testing.assert_allclose(rotation @ np.swapaxes(rotation, 1, 2), identity, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rotation), 1.0, atol=1e-12)


def test_rigid_transforms_map_points_like_pyquaternion_rotate_and_translate(rng):
    translation_m, rotation = random_poses(rng)
    points_Y = rng.uniform(-50, 50, size=(N, 3))
    expected = np.stack([Quaternion(q).rotate(p) + t for q, p, t in zip(rotation, points_Y, translation_m)])
    X_from_Y = geometry.rigid_transforms(translation_m, rotation)
    assert X_from_Y.shape == (N, 4, 4)
    np.testing.assert_allclose(X_from_Y[:, 3], np.broadcast_to([0, 0, 0, 1.0], (N, 4)), atol=0)
    np.testing.assert_allclose(geometry.transform_points(X_from_Y, points_Y), expected, rtol=0, atol=1e-9)


def test_rigid_transforms_equal_devkit_transform_matrix(rng):
    from nuscenes.utils.geometry_utils import transform_matrix

    translation_m, rotation = random_poses(rng, 50)
    X_from_Y = geometry.rigid_transforms(translation_m, rotation)
    for i in range(50):
        np.testing.assert_allclose(X_from_Y[i], transform_matrix(translation_m[i], Quaternion(rotation[i])), atol=1e-12)
        np.testing.assert_allclose(
            geometry.invert_rigid(X_from_Y[i]),
            transform_matrix(translation_m[i], Quaternion(rotation[i]), inverse=True),
            rtol=0,
            atol=1e-9,
        )


def test_invert_rigid_composes_to_identity_both_ways(rng):
    X_from_Y = geometry.rigid_transforms(*random_poses(rng))
    Y_from_X = geometry.invert_rigid(X_from_Y)
    identity = np.broadcast_to(np.eye(4), X_from_Y.shape)
    np.testing.assert_allclose(X_from_Y @ Y_from_X, identity, atol=1e-9)
    np.testing.assert_allclose(Y_from_X @ X_from_Y, identity, atol=1e-9)
    np.testing.assert_array_equal(geometry.invert_rigid(Y_from_X)[:, :3, :3], X_from_Y[:, :3, :3])


def test_transform_points_chain_equals_composed_transform(rng):
    global_from_ego = geometry.rigid_transforms(*random_poses(rng, 20))
    ego_from_sensor = geometry.rigid_transforms(rng.uniform(-2, 2, size=(20, 3)), random_poses(rng, 20)[1])
    points_sensor = rng.uniform(-30, 30, size=(20, 100, 3))
    chained = geometry.transform_points(global_from_ego, geometry.transform_points(ego_from_sensor, points_sensor))
    composed = geometry.transform_points(global_from_ego @ ego_from_sensor, points_sensor)
    np.testing.assert_allclose(chained, composed, rtol=0, atol=1e-9)


def test_transform_points_broadcasts_one_transform_over_any_shape(rng):
    X_from_Y = geometry.rigid_transforms(*random_poses(rng, 1))[0]
    points_Y = rng.uniform(-30, 30, size=(4, 5, 3))
    one_by_one = np.stack([geometry.transform_points(X_from_Y, p) for p in points_Y.reshape(-1, 3)]).reshape(4, 5, 3)
    np.testing.assert_allclose(geometry.transform_points(X_from_Y, points_Y), one_by_one, rtol=0, atol=1e-12)


def test_transform_points_stack_takes_one_point_or_k_points_per_transform(rng):
    X_from_Y = geometry.rigid_transforms(*random_poses(rng, 6))
    single = rng.uniform(-30, 30, size=(6, 3))
    several = rng.uniform(-30, 30, size=(6, 8, 3))
    np.testing.assert_allclose(
        geometry.transform_points(X_from_Y, single),
        np.stack([geometry.transform_points(X_from_Y[i], single[i]) for i in range(6)]),
        rtol=0, atol=1e-12,
    )
    np.testing.assert_allclose(
        geometry.transform_points(X_from_Y, several),
        np.stack([geometry.transform_points(X_from_Y[i], several[i]) for i in range(6)]),
        rtol=0, atol=1e-12,
    )
    with pytest.raises(ValueError, match="do not fit"):
        geometry.transform_points(X_from_Y, rng.uniform(size=(2, 6, 8, 3)))


def test_box_corners_equal_devkit_box_corners(rng):
    from nuscenes.utils.data_classes import Box

    center_m, rotation = random_poses(rng)
    size_wlh_m = rng.uniform(0.3, 15.0, size=(N, 3))
    rotation = rotation * rng.uniform(0.5, 2.0, size=(N, 1))  # Box normalises through rotation_matrix too
    corners = geometry.box_corners(center_m, size_wlh_m, rotation)
    assert corners.shape == (N, 8, 3)
    expected = np.stack([Box(c, s, Quaternion(q)).corners().T for c, s, q in zip(center_m, size_wlh_m, rotation)])
    np.testing.assert_allclose(corners, expected, rtol=0, atol=1e-9)


def test_box_corners_front_face_is_first_for_an_axis_aligned_box():
    corners = geometry.box_corners([[10.0, 0, 0]], [[2.0, 4.0, 1.5]], [[1.0, 0, 0, 0]])[0]
    np.testing.assert_array_equal(corners[:4, 0], 12.0)  # front face at x = centre + l / 2
    np.testing.assert_array_equal(corners[4:, 0], 8.0)
    np.testing.assert_array_equal(corners[:, 1], [1, -1, -1, 1, 1, -1, -1, 1])
    np.testing.assert_array_equal(corners[:, 2], [0.75, 0.75, -0.75, -0.75] * 2)


def test_box_corners_accept_rotation_matrices(rng):
    center_m, rotation = random_poses(rng, 20)
    size_wlh_m = rng.uniform(0.3, 15.0, size=(20, 3))
    np.testing.assert_array_equal(
        geometry.box_corners(center_m, size_wlh_m, quaternions.rotation_matrices(rotation)),
        geometry.box_corners(center_m, size_wlh_m, rotation),
    )


def test_view_points_equals_devkit_for_perspective_and_orthographic_views(rng):
    from nuscenes.utils.geometry_utils import view_points

    intrinsic = np.array([[1266.4, 0.0, 816.3], [0.0, 1266.4, 491.5], [0.0, 0.0, 1.0]])
    points_camera = rng.uniform([-20, -10, 0.2], [20, 10, 80], size=(N, 3))
    views = ((intrinsic, True), (intrinsic, False), (rng.normal(size=(3, 4)), False), (np.eye(2), False))
    for view, normalize in views:
        expected = view_points(points_camera.T, view, normalize=normalize).T
        projected = geometry.view_points(points_camera, view, normalize=normalize)
        np.testing.assert_allclose(projected, expected, rtol=1e-13, atol=1e-9)


def test_view_points_with_3x4_and_4x4_views_adds_the_translation_before_normalising(rng):
    """A projection matrix K [R | t] (3x4) and its 4x4 padding: the fourth column must be added before the
    division by depth (not after, not dropped)."""
    from nuscenes.utils.geometry_utils import view_points

    intrinsic = np.array([[1266.4, 0.0, 816.3], [0.0, 1266.4, 491.5], [0.0, 0.0, 1.0]])
    rotation = Quaternion(axis=[0.1, 1.0, 0.2], angle=0.05).rotation_matrix
    projection = intrinsic @ np.c_[rotation, [0.4, -0.3, 2.5]]  # (3, 4)
    points_camera = rng.uniform([-20, -10, 0.5], [20, 10, 80], size=(N, 3))
    for view in (projection, np.r_[projection, [[0.0, 0.0, 0.0, 1.0]]]):
        for normalize in (True, False):
            expected = view_points(points_camera.T, view, normalize=normalize).T
            projected = geometry.view_points(points_camera, view, normalize=normalize)
            np.testing.assert_allclose(projected, expected, rtol=1e-12, atol=1e-9)
    # Independently: the pinhole projection of the moved points.
    moved = points_camera @ rotation.T + [0.4, -0.3, 2.5]
    uv = moved @ intrinsic.T
    np.testing.assert_allclose(geometry.view_points(points_camera, projection, normalize=True)[:, :2],
                               uv[:, :2] / uv[:, 2:3], rtol=1e-12)


def test_view_points_takes_one_intrinsic_per_box(rng):
    from nuscenes.utils.geometry_utils import view_points

    intrinsics = np.tile(np.eye(3), (10, 1, 1))
    intrinsics[:, [0, 1], [0, 1]] = rng.uniform(500, 2000, size=(10, 2))
    intrinsics[:, [0, 1], 2] = rng.uniform(300, 900, size=(10, 2))
    corners_camera = rng.uniform([-20, -10, 0.2], [20, 10, 80], size=(10, 8, 3))
    projected = geometry.view_points(corners_camera, intrinsics, normalize=True)
    for i in range(10):
        expected = view_points(corners_camera[i].T, intrinsics[i], normalize=True).T
        np.testing.assert_allclose(projected[i], expected, rtol=1e-13)


def test_quaternion_slerp_equals_pyquaternion_slerp(rng):
    q0, q1 = random_quaternions(rng), random_quaternions(rng)
    amount = rng.uniform(-0.25, 1.25, size=N)  # pyquaternion clips to [0, 1]
    amount[:10] = [0, 1, 0, 1, 0.5, 0, 1, 0.25, 0.75, 1]
    expected = np.stack([Quaternion.slerp(Quaternion(a), Quaternion(b), t).q for a, b, t in zip(q0, q1, amount)])
    np.testing.assert_allclose(quaternions.quaternion_slerp(q0, q1, amount), expected, rtol=0, atol=1e-12)


def test_quaternion_slerp_takes_the_short_arc_by_negating_q0_like_pyquaternion(rng):
    q0 = random_quaternions(rng, 50)
    q1 = -q0 + rng.normal(scale=0.1, size=q0.shape)  # dot < 0: pyquaternion flips q0, not q1
    amount = rng.uniform(0, 1, size=50)
    expected = np.stack([Quaternion.slerp(Quaternion(a), Quaternion(b), t).q for a, b, t in zip(q0, q1, amount)])
    np.testing.assert_allclose(quaternions.quaternion_slerp(q0, q1, amount), expected, rtol=0, atol=1e-12)


def test_quaternion_slerp_of_nearly_identical_quaternions_is_normalised_lerp_like_pyquaternion(rng):
    q0 = random_quaternions(rng, 100)
    q1 = q0 + rng.normal(scale=1e-3, size=q0.shape) * np.linalg.norm(q0, axis=1, keepdims=True)
    q1[:20] = q0[:20]  # identical ends: dot == 1
    q1[20:30] = -q0[20:30]  # same rotation, opposite sign
    amount = rng.uniform(0, 1, size=100)
    expected = np.stack([Quaternion.slerp(Quaternion(a), Quaternion(b), t).q for a, b, t in zip(q0, q1, amount)])
    np.testing.assert_allclose(quaternions.quaternion_slerp(q0, q1, amount), expected, rtol=0, atol=1e-12)


def test_yaw_from_quaternions_equals_pyquaternion_yaw_pitch_roll(rng):
    q = random_quaternions(rng)
    expected = np.array([Quaternion(row).yaw_pitch_roll[0] for row in q])
    np.testing.assert_allclose(quaternions.yaw_from_quaternions(q), expected, rtol=0, atol=1e-12)


def test_heading_equals_devkit_quaternion_yaw_and_yaw_for_rotations_about_z(rng):
    from nuscenes.eval.common.utils import quaternion_yaw

    q = random_quaternions(rng)
    np.testing.assert_allclose(
        quaternions.heading_from_quaternions(q), [quaternion_yaw(Quaternion(row)) for row in q], rtol=0, atol=1e-12
    )
    yaw = rng.uniform(-np.pi, np.pi, size=N)
    about_z = np.stack([np.cos(yaw / 2), np.zeros(N), np.zeros(N), np.sin(yaw / 2)], axis=1)
    np.testing.assert_allclose(quaternions.yaw_from_quaternions(about_z), yaw, rtol=0, atol=1e-12)
    np.testing.assert_allclose(quaternions.heading_from_quaternions(about_z), yaw, rtol=0, atol=1e-12)


def devkit_point_counts(corners_boxes: list, points: np.ndarray) -> list[int]:
    from nuscenes.utils.data_classes import Box
    from nuscenes.utils.geometry_utils import points_in_box

    return [int(points_in_box(Box(center, wlh, Quaternion(q)), points.T).sum()) for center, wlh, q in corners_boxes]


def test_count_points_in_boxes_equals_devkit_points_in_box_faces_included(rng):
    """Rotated boxes (their axis-aligned bounds hold points outside them), points exactly on faces and corners of
    an axis-aligned box (the devkit's `>= 0` and `<= |edge|^2`), a box beyond every point's x, and a last box with
    no point (the counts keep one entry per box)."""
    boxes = [(rng.uniform(-20, 20, 3), rng.uniform(1, 5, 3), random_quaternions(rng, 1)[0]) for _ in range(30)]
    boxes.append(((0.0, 0.0, 0.0), (2.0, 4.0, 2.0), (1.0, 0.0, 0.0, 0.0)))  # x in [-2, 2], y and z in [-1, 1]
    boxes.append(((1000.0, 0.0, 0.0), (1.0, 1.0, 1.0), (1.0, 0.0, 0.0, 0.0)))  # beyond every point
    boxes.append(((-500.0, 0.0, 0.0), (1.0, 1.0, 1.0), (1.0, 0.0, 0.0, 0.0)))  # before every point, and last
    on_faces = np.array([[2.0, 1.0, 1.0], [-2.0, -1.0, -1.0], [2.0, 0.0, 0.0], [-2.0, 0.5, 0.5], [0.0, 1.0, 0.0],
                         [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [2.0 + 1e-12, 0.0, 0.0]])
    points = np.concatenate([rng.uniform(-25, 25, (4000, 3)), on_faces])
    corners = geometry.box_corners(np.array([b[0] for b in boxes]), np.array([b[1] for b in boxes]),
                                   np.array([b[2] for b in boxes]))
    got = geometry.count_points_in_boxes(corners, points)
    expected = devkit_point_counts(boxes, points)
    assert got.dtype == np.int64 and got.tolist() == expected
    assert expected[30] >= 8 and expected[-2:] == [0, 0]  # the face points count; the far boxes hold none
    no_points = geometry.count_points_in_boxes(corners, np.zeros((0, 3)))
    assert no_points.dtype == np.int64 and no_points.tolist() == [0] * len(boxes)


def test_interp_two_points_returns_the_end_values_exactly_like_np_interp():
    """At t == t1 the formula c0 + slope * (t1 - t0) rounds away from c1 for these values, and at t == t0 a
    difference that overflows makes it NaN: numpy returns the end values themselves, so must we."""
    t0, t1 = 516068585547878, 516068585840847
    c0, c1 = -33.93479912248731, 46.99254132161326
    assert (c1 - c0) / (t1 - t0) * (t1 - t0) + c0 != c1  # the case this test is about
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nor a warning about the overflow, as np.interp gives none
        got = geometry.interp_two_points(np.array([t1, t0, t0 + 5]), np.array([t0] * 3), np.array([t1] * 3),
                                         np.array([[c0], [-1e308], [c0]]), np.array([[c1], [1e308], [c1]]))
    expected = [np.interp(t1, [t0, t1], [c0, c1]), np.interp(t0, [t0, t1], [-1e308, 1e308]),
                np.interp(t0 + 5, [t0, t1], [c0, c1])]
    assert got[:, 0].tolist() == expected


def test_equal_sample_times_interpolate_and_slerp_without_warnings():
    """Two samples at the same time (t0 == t1): the centre is c1 and the slerp amount 1, with no division
    warning (x/0 and 0/0 are computed and discarded)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        centres = geometry.interp_two_points(np.array([7, 7]), np.array([7, 7]), np.array([7, 7]),
                                             np.array([[1.0, 2.0], [3.0, 3.0]]), np.array([[5.0, 2.0], [3.0, 3.0]]))
        amounts = geometry.slerp_amount(np.array([7, 5]), np.array([7, 3]), np.array([7, 7]))
    assert centres.tolist() == [[5.0, 2.0], [3.0, 3.0]]
    assert amounts.dtype == np.float64 and amounts.tolist() == [1.0, 0.5]


def test_invert_quaternions_equals_pyquaternions_inverse_for_unit_and_other_norms():
    rng = np.random.default_rng(7)
    q = rng.normal(size=(2, 5, 4)) * rng.uniform(0.2, 3.0, size=(2, 5, 1))  # batched, norms far from 1
    ours = quaternions.invert_quaternions(q)
    assert ours.shape == (2, 5, 4)
    expected = [[Quaternion(*row).inverse.elements for row in block] for block in q]
    np.testing.assert_allclose(ours, expected, rtol=1e-12, atol=0)
    with pytest.raises(ValueError, match=r"q_wxyz must have shape \(\.\.\., 4\), got \(5, 3\)"):
        quaternions.invert_quaternions(np.ones((5, 3)))


def test_quaternion_slerp_keeps_q0_when_the_ends_are_exactly_orthogonal_like_pyquaternion():
    # q0 . q1 == 0 exactly (after normalisation): pyquaternion negates q0 only for dot < 0, so identity to a
    # half turn about z passes through +90 degrees, not -90 (both arcs are equally short: only the rule decides).
    q0 = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0], [0.0, 2.0, 0.0, 0.0]])
    q1 = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0, -1.0], [1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 3.0]])
    amount = np.array([0.5, 0.25, 0.5, 0.75])
    expected = np.stack([Quaternion.slerp(Quaternion(a), Quaternion(b), t).q for a, b, t in zip(q0, q1, amount)])
    np.testing.assert_allclose(expected[0], [np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)], atol=1e-15)  # +90 about z
    np.testing.assert_allclose(quaternions.quaternion_slerp(q0, q1, amount), expected, rtol=0, atol=1e-12)


def test_multiply_quaternions_equals_pyquaternion_product_and_broadcasts(rng):
    p, q = random_quaternions(rng, 50), random_quaternions(rng, 50)  # norms in [0.5, 2]: no normalisation
    expected = np.stack([(Quaternion(a) * Quaternion(b)).elements for a, b in zip(p, q)])
    np.testing.assert_allclose(quaternions.multiply_quaternions(p, q), expected, rtol=1e-12, atol=1e-15)
    one = p[0]
    ours = quaternions.multiply_quaternions(one, q.reshape(5, 10, 4))  # one p times a batch of q
    assert ours.shape == (5, 10, 4)
    np.testing.assert_allclose(ours.reshape(50, 4), [(Quaternion(one) * Quaternion(b)).elements for b in q],
                               rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match=r"p_wxyz must have shape \(\.\.\., 4\), got \(3,\)"):
        quaternions.multiply_quaternions(np.ones(3), q)


def test_vehicle_flat_from_vehicle_equals_the_devkit_render_sample_data_arithmetic(rng):
    q = random_quaternions(rng, 40)  # tilted, any norm: the devkit's arithmetic, not only the upright case
    expected = []
    for row in q:  # nuscenes.py render_sample_data(use_flat_vehicle_coordinates=True), as written
        ego_yaw = Quaternion(row).yaw_pitch_roll[0]
        expected.append(np.dot(Quaternion(scalar=np.cos(ego_yaw / 2), vector=[0, 0, np.sin(ego_yaw / 2)]).rotation_matrix,
                               Quaternion(row).inverse.rotation_matrix))
    ours = quaternions.vehicle_flat_from_vehicle(q.reshape(4, 10, 4))
    assert ours.shape == (4, 10, 3, 3)
    np.testing.assert_allclose(ours.reshape(40, 3, 3), expected, rtol=0, atol=1e-12)
    yaw = 2.5  # an upright ego: the flat frame is the ego frame
    upright = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    np.testing.assert_allclose(quaternions.vehicle_flat_from_vehicle(upright), np.eye(3), rtol=0, atol=1e-12)
