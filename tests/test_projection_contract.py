"""nuparquet.projection's contract beyond the devkit comparisons: which pose columns it reads, the errors that
name what is missing, the default visibility, the types it returns, the devkit's strict lidar depth limit and
the pairing of camera keyframes with lidar keyframes. Expectations are written out by hand."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from nuparquet.geometry import Cameras
from nuparquet.frames import points_in_image as lidar
from nuparquet.frames.boxes import frame_boxes
from nuparquet.frames.projection import boxes_in_cameras, camera_rows, project_boxes
from nuparquet.geometry import box_visibility
from nuparquet.frames.poses import (
    MATRIX_COLUMNS, POSE_COLUMNS, cameras_from_frames, pose_columns, sensor_poses,
)

IDENTITY = [1.0, 0.0, 0.0, 0.0]
QUARTER_TURN_Z = [float(np.sqrt(0.5)), 0.0, 0.0, float(np.sqrt(0.5))]  # 90 degrees about z
K = [[1000.0, 0.0, 800.0], [0.0, 1000.0, 450.0], [0.0, 0.0, 1.0]]


def camera_frame(**columns) -> pl.DataFrame:
    """One camera frame at the origin looking along ego x (camera x right, y down, z forward)."""
    values = {"token": ["f"], "sample_token": ["s1"], "timestamp": [2000], "is_key_frame": [True],
              "width": [1600], "height": [900], "ego_translation": [[0.0, 0.0, 0.0]], "ego_rotation": [IDENTITY],
              "sensor_translation": [[0.0, 0.0, 0.0]], "sensor_rotation": [[0.5, -0.5, 0.5, -0.5]],
              "camera_intrinsic": [K]} | columns
    return pl.DataFrame(values, schema_overrides={
        "ego_translation": pl.Array(pl.Float64, 3), "ego_rotation": pl.Array(pl.Float64, 4),
        "sensor_translation": pl.Array(pl.Float64, 3), "sensor_rotation": pl.Array(pl.Float64, 4),
        "camera_intrinsic": pl.Array(pl.Float64, (3, 3))})


def one_box(x_m: float) -> tuple[pl.DataFrame, pl.DataFrame]:
    annotations = pl.DataFrame(
        {"token": ["a"], "sample_token": ["s1"], "instance_token": ["i"], "category_name": ["vehicle.car"],
         "translation": [[x_m, 0.0, 0.0]], "size": [[2.0, 4.0, 1.5]], "rotation": [IDENTITY]},
        schema_overrides={"translation": pl.Array(pl.Float64, 3), "size": pl.Array(pl.Float64, 3),
                          "rotation": pl.Array(pl.Float64, 4)})
    samples = pl.DataFrame({"token": ["s1"], "timestamp": [2000], "prev": [""]})
    return annotations, samples


def test_pose_columns_prefer_the_stored_matrices_when_both_are_there_even_alone():
    assert pose_columns(list(MATRIX_COLUMNS)) == MATRIX_COLUMNS
    assert pose_columns([*MATRIX_COLUMNS, "token"]) == MATRIX_COLUMNS
    assert pose_columns(["global_from_ego", *POSE_COLUMNS]) == POSE_COLUMNS


def test_sensor_poses_read_the_stored_matrices_or_build_them_from_the_poses():
    global_from_ego = np.eye(4)
    global_from_ego[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]  # 90 degrees about z
    global_from_ego[:3, 3] = [5.0, -2.0, 0.5]
    ego_from_sensor = np.eye(4)
    ego_from_sensor[:3, 3] = [1.0, 0.0, 1.5]
    matrices = pl.DataFrame({"global_from_ego": [global_from_ego.ravel().tolist()],
                             "ego_from_sensor": [ego_from_sensor.ravel().tolist()]})  # only these two columns
    got = sensor_poses(matrices)
    np.testing.assert_array_equal(got[0][0], global_from_ego)
    np.testing.assert_array_equal(got[1][0], ego_from_sensor)
    poses = camera_frame(ego_translation=[[5.0, -2.0, 0.5]], ego_rotation=[QUARTER_TURN_Z],
                         sensor_translation=[[1.0, 0.0, 1.5]], sensor_rotation=[IDENTITY])
    built = sensor_poses(poses)
    np.testing.assert_allclose(built[0][0], global_from_ego, atol=1e-15)
    np.testing.assert_allclose(built[1][0], ego_from_sensor, atol=1e-15)


def test_missing_pose_and_camera_columns_are_named():
    with pytest.raises(ValueError) as error:
        sensor_poses(camera_frame().drop("ego_rotation", "sensor_rotation"))
    assert str(error.value) == ("frames lacks column(s) ego_rotation, sensor_rotation "
                                "(or global_from_ego and ego_from_sensor)")
    with pytest.raises(ValueError) as error:
        cameras_from_frames(camera_frame().drop("width", "height"))
    assert str(error.value) == "frames lacks column(s) width, height"
    lidar_row = camera_frame(camera_intrinsic=[None])
    with pytest.raises(ValueError) as error:
        cameras_from_frames(lidar_row)
    assert str(error.value) == "cameras_from_frames needs camera rows: some rows have no camera_intrinsic"
    with pytest.raises(ValueError) as error:
        camera_rows(camera_frame().drop("timestamp"))
    assert str(error.value) == "frames lacks column(s) timestamp"


def test_frame_boxes_names_the_table_and_the_columns_it_lacks():
    frames = camera_frame()
    annotations, samples = one_box(10.0)
    with pytest.raises(ValueError) as error:
        frame_boxes(frames, annotations, samples.drop("prev"))
    assert str(error.value) == "samples lacks column(s) prev"
    with pytest.raises(ValueError) as error:
        frame_boxes(frames, annotations.drop("size", "rotation"), samples)
    assert str(error.value) == "annotations lacks column(s) size, rotation"
    with pytest.raises(ValueError) as error:
        frame_boxes(frames.drop("is_key_frame"), annotations, samples)
    assert str(error.value) == "frames lacks column(s) is_key_frame"


def test_project_boxes_keeps_visible_boxes_by_default_and_names_the_visibilities():
    frames = camera_frame()
    annotations, samples = one_box(-10.0)  # behind the camera: projected by "none" only
    assert len(project_boxes(frames, annotations, samples, visibility="none")) == 1
    assert len(project_boxes(frames, annotations, samples)) == 0
    ahead, _ = one_box(10.0)
    projected = project_boxes(frames, ahead, samples)
    assert len(projected) == 1 and projected.frame_index.dtype == np.int64
    with pytest.raises(ValueError) as error:
        project_boxes(frames, annotations, samples, visibility="ANY")
    assert str(error.value) == "visibility must be one of any, all, none, got 'ANY'"


def test_frame_index_counts_rows_of_the_frames_given_including_non_cameras():
    frames = pl.concat([camera_frame(token=["lidar"], camera_intrinsic=[None]), camera_frame()], how="vertical")
    annotations, samples = one_box(10.0)
    projected = project_boxes(frames, annotations, samples)
    assert projected.frame_index.tolist() == [1] and projected.frame_index.dtype == np.int64


def identity_camera() -> Cameras:
    return Cameras.from_poses(np.eye(4)[None], np.eye(4)[None], np.array(K)[None], [[1600.0, 900.0]])


def test_lidar_points_exactly_at_the_minimum_depth_are_dropped_like_the_devkit():
    """devkit map_pointcloud_to_image keeps `depths > min_dist` (1 m): a point at exactly 1 m is dropped; points
    are kept 1 px inside the image (1 < u < width - 1)."""
    points = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.001], [0.0, 0.0, 0.5], [0.0, 0.0, 20.0],
                       [0.7995 * 2.0, 0.0, 2.0],   # u = 1599.5: inside the image, outside the 1-pixel margin
                       [0.7985 * 2.0, 0.0, 2.0]])  # u = 1598.5
    uv, depth, index = lidar.points_in_image(points, np.eye(4), np.eye(4), identity_camera())
    assert index.tolist() == [1, 3, 5]
    np.testing.assert_allclose(uv, [[800.0, 450.0], [800.0, 450.0], [1598.5, 450.0]], atol=1e-9)
    np.testing.assert_allclose(depth, [1.001, 20.0, 2.0], rtol=1e-15)
    with pytest.raises(ValueError) as error:
        lidar.points_in_image(points, np.eye(4), np.eye(4), identity_camera().take([0, 0]))
    assert str(error.value) == "points_in_image takes one camera, got 2"


def test_lidar_for_cameras_pairs_camera_keyframes_with_the_first_lidar_keyframe_of_their_sample():
    cameras = pl.DataFrame({"sample_token": ["s1", "s2", "s1", "s3", "s2"],
                            "is_key_frame": [True, True, False, True, True]})
    lidar_rows = pl.DataFrame({"sample_token": ["s2", "s1", "s2"]})  # s2 twice: its first row counts; s3 has none
    got = lidar.lidar_for_cameras(cameras, lidar_rows)
    assert got.dtype == np.int64
    assert got.tolist() == [1, 0, -1, -1, 0]


def test_box_visibility_uses_the_devkit_strict_depth_limits():
    """box_in_image: a corner counts only deeper than 1 m (1.0 exactly is not), a box is in front only if every
    corner is deeper than 0.1 m (0.1 exactly is not); pixels are all inside the image here."""
    corners_px = np.full((3, 8, 2), [800.0, 450.0])
    depths = np.array([[1.0] * 8, [1.5] + [1.0] * 7, [1.5] * 7 + [0.1]])
    camera = identity_camera().take([0, 0, 0])
    corner_visible, in_front, visible = box_visibility(corners_px, depths, camera.size_px, camera.scale)
    assert corner_visible.tolist() == [[False] * 8, [True] + [False] * 7, [True] * 7 + [False]]
    assert in_front.tolist() == [True, True, False] and visible.tolist() == [False, True, False]


def test_boxes_in_cameras_moves_the_centre_into_the_ego_frame_and_the_camera():
    """The ego at global x = 5 looking along +x; a box at global x = 15 is 10 m ahead: ego (10, 0, 0), camera
    (x right, y down, z forward) (0, 0, 10)."""
    frames = camera_frame(ego_translation=[[5.0, 0.0, 0.0]])
    annotations, samples = one_box(15.0)
    boxes = frame_boxes(frames, annotations, samples)
    seen = boxes_in_cameras(cameras_from_frames(frames), boxes)
    np.testing.assert_allclose(seen.center_ego_m, [[10.0, 0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(seen.center_camera_m, [[0.0, 0.0, 10.0]], atol=1e-12)
    # corners: length 4 along ego x (camera z), width 2 along ego y (camera -x), height 1.5 (camera -y)
    np.testing.assert_allclose(np.sort(np.unique(seen.corners_camera_m[0, :, 2])), [8.0, 12.0], atol=1e-12)
    np.testing.assert_allclose(np.sort(np.unique(seen.corners_camera_m[0, :, 0])), [-1.0, 1.0], atol=1e-12)
