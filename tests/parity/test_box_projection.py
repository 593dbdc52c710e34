"""nuparquet.projection and nuparquet.frames.boxes against nuscenes-devkit: boxes in images, interpolated sweep boxes, lidar points.

The parity tests read the converted Parquet (`OUT/frames`, `OUT/annotations`, `OUT/tables/sample`) and compare
every camera frame of a scene (keyframes and sweeps, all six cameras) with the devkit reading the source JSON.
The small tests at the end pin get_boxes' edge cases on hand-written tables.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from nuparquet.sources.points import read_lidar_bin
from nuparquet.frames.boxes import boxes_for_frames
from nuparquet.frames.projection import project_boxes
from nuparquet.frames.poses import cameras_from_frames, sensor_poses
from nuparquet.frames.points_in_image import points_in_image

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit's explorer imports pyplot; never open a window

from conftest import EXTRACT_VERSION, IRREGULAR_VERSION, SYNTH_VERSION

PARITY_SCENE = "scene-0916"  # busy parking lot: ~1400 camera frames, ~85k (frame, box) pairs
CORNER_TOLERANCE_PX = 1e-6
# The devkit rounds lidar points to float32 after every transform step: at ~1e3 m global coordinates that is
# ~1e-4 m, which the camera turns into (focal ~1266 px) x 1e-4 m / depth pixels. We compute in float64, so the
# difference is bounded by a pixel error that shrinks with depth (observed: 0.06 px, 0.13 px*m on the extract).
LIDAR_TOLERANCE_PX_M = 0.5  # pixel error x depth in metres: 0.5 px at the 1 m minimum depth, 0.01 px at 50 m
LIDAR_EDGE_TOLERANCE_PX = 0.5
LIDAR_DEPTH_TOLERANCE_M = 1e-3


def read_out(out: Path, scene_name: str | None = None) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame]:
    """Camera frames and annotations (of one scene, or all) and the sample table of a converted dataset."""
    frames = pl.scan_parquet(out / "frames" / "*.parquet").filter(pl.col("modality") == "camera")
    annotations = pl.scan_parquet(out / "annotations" / "*.parquet")
    if scene_name is not None:
        frames = frames.filter(pl.col("scene_name") == scene_name)
        annotations = annotations.filter(pl.col("scene_name") == scene_name)
    samples = pl.read_parquet(out / "tables" / "sample" / "*.parquet")
    return frames.collect(), annotations.collect(), samples


def load_devkit(devkit, dataroot: Path, version: str):
    return devkit.NuScenes(version=version, dataroot=str(dataroot), verbose=False)


def assert_boxes_match_devkit(nusc, frames: pl.DataFrame, annotations, samples) -> dict:
    """For every frame: the devkit's get_sample_data boxes (ANY, ALL, NONE) are ours, corner for corner."""
    from nuscenes.utils.geometry_utils import BoxVisibility, box_in_image, view_points

    ours = project_boxes(frames, annotations, samples, visibility="none")
    row_of = {key: row for row, key in enumerate(zip(ours.frame_token, ours.annotation_token))}
    tokens_of_frame: dict[str, set[str]] = {}
    for frame_token, annotation_token in row_of:
        tokens_of_frame.setdefault(frame_token, set()).add(annotation_token)
    passes_all = ours.corner_visible.all(axis=1) & ours.in_front

    ours_rows, devkit_corners_px, devkit_depths = [], [], []
    counts = {"frames": 0, "none": 0, "any": 0, "all": 0, "sweeps": 0, "near_in_view": 0}
    for frame in frames.select("token", "width", "height", "is_key_frame").iter_rows(named=True):
        # get_sample_data(token, level) filters get_sample_data(token, NONE) by box_in_image(box, K, size, level):
        # one devkit call per frame and level-wise filtering is the same computation at a third of the cost.
        _, boxes, intrinsic = nusc.get_sample_data(frame["token"], box_vis_level=BoxVisibility.NONE)
        imsize = (frame["width"], frame["height"])
        ours_here = tokens_of_frame.get(frame["token"], set())
        assert ours_here == {box.token for box in boxes}, f"boxes of frame {frame['token']}"
        for level, ours_pass in ((BoxVisibility.ANY, ours.visible), (BoxVisibility.ALL, passes_all)):
            devkit_set = {box.token for box in boxes if box_in_image(box, intrinsic, imsize, vis_level=level)}
            ours_set = {token for token in ours_here if ours_pass[row_of[frame["token"], token]]}
            assert ours_set == devkit_set, f"{level} boxes of frame {frame['token']}"
            counts["any" if level == BoxVisibility.ANY else "all"] += len(devkit_set)
        for box in boxes:
            corners_camera = box.corners()
            centre_px = view_points(box.center[:, None], intrinsic, normalize=True)[:2, 0]
            if ((corners_camera[2] > 0.1).all() and (corners_camera[2] <= 1.0).all()
                    and 0 < centre_px[0] < imsize[0] and 0 < centre_px[1] < imsize[1]):
                counts["near_in_view"] += 1  # in front and in view, yet dropped: corners count beyond 1 m only
            ours_rows.append(row_of[frame["token"], box.token])
            devkit_corners_px.append(view_points(corners_camera, intrinsic, normalize=True)[:2].T)
            devkit_depths.append(corners_camera[2])
        counts["frames"] += 1
        counts["sweeps"] += not frame["is_key_frame"]
        counts["none"] += len(boxes)

    rows = np.array(ours_rows, dtype=np.int64)
    devkit_corners_px, devkit_depths = np.array(devkit_corners_px), np.array(devkit_depths)
    np.testing.assert_allclose(ours.depths[rows], devkit_depths, rtol=0, atol=1e-9)
    # Pixels are compared where the devkit draws them (ANY): a corner at depth ~0 projects to ~infinity.
    drawn = ours.visible[rows]
    pixel_error = np.abs(ours.corners_px[rows][drawn] - devkit_corners_px[drawn]).max(initial=0.0)
    assert pixel_error <= CORNER_TOLERANCE_PX
    counts["max_corner_error_px"] = pixel_error

    # The filtered calls return exactly the filtered subsets of the unfiltered one.
    for visibility, mask in (("any", ours.visible), ("all", passes_all)):
        kept = project_boxes(frames, annotations, samples, visibility=visibility)
        np.testing.assert_array_equal(kept.annotation_token, ours.annotation_token[mask])
        np.testing.assert_array_equal(kept.frame_token, ours.frame_token[mask])
        np.testing.assert_array_equal(kept.corners_px, ours.corners_px[mask])
    return counts


def assert_sweep_boxes_match_devkit_get_boxes(nusc, frames: pl.DataFrame, annotations, samples) -> int:
    """Interpolated centres and rotations equal the devkit's get_boxes, to 1e-12."""
    boxes = boxes_for_frames(frames.filter(~pl.col("is_key_frame")), annotations, samples)
    row_of = {key: row for row, key in enumerate(zip(boxes["frame_token"], boxes["annotation_token"]))}
    ours_rows, devkit_centers, devkit_rotations = [], [], []
    for frame_token in frames.filter(~pl.col("is_key_frame"))["token"]:
        devkit_boxes = nusc.get_boxes(frame_token)
        assert len(devkit_boxes) == int((boxes["frame_token"] == frame_token).sum())
        for box in devkit_boxes:
            ours_rows.append(row_of[frame_token, box.token])
            devkit_centers.append(box.center)
            devkit_rotations.append(box.orientation.q)
    rows = np.array(ours_rows, dtype=np.int64)
    translation = boxes["translation"].to_numpy().reshape(-1, 3)[rows]
    rotation = boxes["rotation"].to_numpy().reshape(-1, 4)[rows]
    np.testing.assert_allclose(translation, np.array(devkit_centers).reshape(-1, 3), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rotation, np.array(devkit_rotations).reshape(-1, 4), rtol=0, atol=1e-12)
    return len(rows)


def devkit_projection_of_all_points(nusc, monkeypatch, lidar_token: str, camera_token: str):
    """The devkit's map_pointcloud_to_image before its mask: (P, 2) pixels and (P,) depths for every point,
    and the (K, 2) pixels it returns. The devkit returns no point indices, so we record its view_points call."""
    import nuscenes.nuscenes as devkit_module

    recorded = {}
    devkit_view_points = devkit_module.view_points

    def recording_view_points(points, view, normalize):
        projected = devkit_view_points(points, view, normalize)
        recorded["depth_m"], recorded["uv"] = np.array(points[2], dtype=np.float64), projected[:2].T.copy()
        return projected

    monkeypatch.setattr(devkit_module, "view_points", recording_view_points)
    kept, _, image = nusc.explorer.map_pointcloud_to_image(lidar_token, camera_token)
    monkeypatch.setattr(devkit_module, "view_points", devkit_view_points)
    return recorded["uv"], recorded["depth_m"], kept[:2].T, image.size


def assert_lidar_matches_devkit(nusc, monkeypatch, out: Path, dataroot: Path, scene_name: str | None) -> dict:
    """Every keyframe camera image of the scene with the LIDAR_TOP keyframe of its sample."""
    frames = pl.scan_parquet(out / "frames" / "*.parquet").filter(pl.col("is_key_frame"))
    if scene_name is not None:
        frames = frames.filter(pl.col("scene_name") == scene_name)
    frames = frames.collect()
    lidar_frames = frames.filter(pl.col("channel") == "LIDAR_TOP")
    lidar_of_sample = {token: row for row, token in enumerate(lidar_frames["sample_token"].to_list())}
    global_from_ego, ego_from_lidar = sensor_poses(lidar_frames)
    cameras_df = frames.filter(pl.col("modality") == "camera")
    cameras = cameras_from_frames(cameras_df)  # once for every image
    counts = {"images": 0, "points": 0, "boundary_points": 0, "max_error_px": 0.0, "max_depth_error_m": 0.0,
              "near_points": 0}
    for index_of_camera, camera in enumerate(cameras_df.iter_rows(named=True)):
        row = lidar_of_sample[camera["sample_token"]]
        lidar = lidar_frames.row(row, named=True)
        points_lidar = read_lidar_bin(dataroot / lidar["filename"])
        uv, depth_m, index = points_in_image(points_lidar, global_from_ego[row], ego_from_lidar[row],
                                            cameras.take([index_of_camera]))
        devkit_uv, devkit_depth_m, devkit_kept_uv, (width, height) = devkit_projection_of_all_points(
            nusc, monkeypatch, lidar["token"], camera["token"]
        )
        assert (width, height) == (camera["width"], camera["height"])

        devkit_keep = (
            (devkit_depth_m > 1.0)
            & (devkit_uv[:, 0] > 1) & (devkit_uv[:, 0] < width - 1)
            & (devkit_uv[:, 1] > 1) & (devkit_uv[:, 1] < height - 1)
        )
        np.testing.assert_array_equal(devkit_uv[devkit_keep], devkit_kept_uv)  # we recorded the right call
        counts["near_points"] += int(((devkit_depth_m > 0.1) & (devkit_depth_m <= 1.0) & (devkit_uv[:, 0] > 1)
                                      & (devkit_uv[:, 0] < width - 1) & (devkit_uv[:, 1] > 1)
                                      & (devkit_uv[:, 1] < height - 1)).sum())  # in view, dropped by min_dist

        # Points either side of a filter edge only by the devkit's float32 rounding may differ; no others.
        differ = np.setxor1d(index, np.flatnonzero(devkit_keep))
        margin_px = np.minimum.reduce([
            np.abs(devkit_uv[differ, 0] - 1), np.abs(devkit_uv[differ, 0] - (width - 1)),
            np.abs(devkit_uv[differ, 1] - 1), np.abs(devkit_uv[differ, 1] - (height - 1)),
        ]) if len(differ) else np.zeros(0)
        near_depth_limit = np.abs(devkit_depth_m[differ] - 1.0) < LIDAR_DEPTH_TOLERANCE_M
        near_edge = (margin_px < LIDAR_EDGE_TOLERANCE_PX) | near_depth_limit
        assert near_edge.all(), f"points {differ[~near_edge]} of {lidar['token']} in {camera['token']}"

        both = np.isin(index, np.flatnonzero(devkit_keep))
        errors_px = np.abs(uv[both] - devkit_uv[index[both]]).max(axis=1, initial=0.0)
        error_px = errors_px.max(initial=0.0)
        depth_error_m = np.abs(depth_m[both] - devkit_depth_m[index[both]]).max(initial=0.0)
        assert (errors_px * depth_m[both]).max(initial=0.0) < LIDAR_TOLERANCE_PX_M
        assert depth_error_m < LIDAR_DEPTH_TOLERANCE_M
        counts["images"] += 1
        counts["points"] += int(both.sum())
        counts["boundary_points"] += len(differ)
        counts["max_error_px"] = max(counts["max_error_px"], error_px)
        counts["max_depth_error_m"] = max(counts["max_depth_error_m"], depth_error_m)
    return counts


# ---------------------------------------------------------------------------------------------- real extract


@pytest.fixture(scope="module")
def extract_devkit(devkit, extract_root):
    return load_devkit(devkit, extract_root, EXTRACT_VERSION)


@pytest.fixture(scope="module")
def extract_scene(extract_out):
    return read_out(extract_out, PARITY_SCENE)


@pytest.mark.real
@pytest.mark.devkit
def test_boxes_in_every_camera_frame_of_a_scene_equal_devkit_get_sample_data(extract_devkit, extract_scene):
    counts = assert_boxes_match_devkit(extract_devkit, *extract_scene)
    # Six cameras at ~12 Hz over ~20 s: both keyframes and sweeps were compared, with boxes in view.
    assert counts["frames"] > 1000 and counts["sweeps"] > 800 and counts["any"] > 10000 and counts["all"] > 5000


@pytest.mark.real
@pytest.mark.devkit
def test_interpolated_sweep_boxes_equal_devkit_get_boxes(extract_devkit, extract_scene):
    assert assert_sweep_boxes_match_devkit_get_boxes(extract_devkit, *extract_scene) > 50000


@pytest.mark.real
@pytest.mark.devkit
def test_lidar_points_in_keyframe_images_equal_devkit_map_pointcloud_to_image(
    extract_devkit, extract_out, extract_root, monkeypatch
):
    counts = assert_lidar_matches_devkit(extract_devkit, monkeypatch, extract_out, extract_root, PARITY_SCENE)
    assert counts["images"] == 41 * 6 and counts["points"] > 100000


# ---------------------------------------------------------------------------------------------- synthetic data


@pytest.fixture(scope="module", params=["synth", "irregular"])
def synth(request, devkit):
    """The regular synthetic dataset, and the irregular one (boxes and lidar points 0.05-1.5 m in front of
    CAM_FRONT, tracks with gaps that get_boxes must not interpolate across, hills)."""
    if request.param == "irregular":
        root, out = request.getfixturevalue("irregular_root"), request.getfixturevalue("irregular_out")
        return root, out, load_devkit(devkit, root, IRREGULAR_VERSION)
    root, out = request.getfixturevalue("synth_root"), request.getfixturevalue("synth_out")
    return root, out, load_devkit(devkit, root, SYNTH_VERSION)


@pytest.mark.devkit
def test_synthetic_boxes_equal_devkit_get_sample_data(synth):
    root, out, nusc = synth
    counts = assert_boxes_match_devkit(nusc, *read_out(out))
    assert counts["frames"] > 0 and counts["any"] > 0
    if IRREGULAR_VERSION in {p.name for p in root.iterdir()}:
        assert counts["near_in_view"] >= 2  # the boxes 0.5 and 0.8 m in front of CAM_FRONT were compared


@pytest.mark.devkit
def test_synthetic_sweep_boxes_equal_devkit_get_boxes(synth):
    _, out, nusc = synth
    frames, annotations, samples = read_out(out)
    assert not frames["is_key_frame"].all()  # the generator writes sweeps: a regression there must fail, not skip
    assert assert_sweep_boxes_match_devkit_get_boxes(nusc, frames, annotations, samples) > 0


@pytest.mark.devkit
def test_synthetic_lidar_points_equal_devkit_map_pointcloud_to_image(synth, monkeypatch):
    root, out, nusc = synth
    counts = assert_lidar_matches_devkit(nusc, monkeypatch, out, root, None)
    assert counts["images"] > 0
    if IRREGULAR_VERSION in {p.name for p in root.iterdir()}:
        assert counts["near_points"] > 50  # points on the boxes just in front of CAM_FRONT, nearer than 1 m


# ---------------------------------------------------------------------------------- get_boxes on small tables

IDENTITY = [1.0, 0.0, 0.0, 0.0]


def about_z(yaw: float) -> list[float]:
    return [float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2))]


def small_tables(frame_timestamp: int, is_key_frame: bool = False, frame_sample: str = "s1"):
    """Two samples (s0 at t=1000 us, s1 at t=2000 us) and one camera frame looking along ego x from the origin.

    Instance "both" moves from x=10 to x=20 and turns 90 degrees; "new" appears in s1; "gone" is only in s0.
    """
    samples = pl.DataFrame({"token": ["s0", "s1"], "timestamp": [1000, 2000], "prev": ["", "s0"]})
    annotation_rows = [
        ("a-both-0", "s0", "both", [10.0, 0.0, 0.0], IDENTITY),
        ("a-gone-0", "s0", "gone", [15.0, 3.0, 0.0], IDENTITY),
        ("a-both-1", "s1", "both", [20.0, 0.0, 0.0], about_z(np.pi / 2)),
        ("a-new-1", "s1", "new", [30.0, -2.0, 0.0], about_z(0.3)),
    ]
    annotations = pl.DataFrame(
        {
            "token": [r[0] for r in annotation_rows],
            "sample_token": [r[1] for r in annotation_rows],
            "instance_token": [r[2] for r in annotation_rows],
            "category_name": ["vehicle.car"] * len(annotation_rows),
            "translation": [r[3] for r in annotation_rows],
            "size": [[2.0, 4.0, 1.5]] * len(annotation_rows),
            "rotation": [r[4] for r in annotation_rows],
        },
        schema_overrides={"translation": pl.Array(pl.Float64, 3), "size": pl.Array(pl.Float64, 3),
                          "rotation": pl.Array(pl.Float64, 4)},
    )
    # Camera axes (x right, y down, z forward) in the ego frame (x forward, y left, z up).
    ego_from_camera_rotation = [0.5, -0.5, 0.5, -0.5]
    frames = pl.DataFrame(
        {
            "token": ["f"], "sample_token": [frame_sample], "timestamp": [frame_timestamp],
            "is_key_frame": [is_key_frame],
            "width": [1600], "height": [900],
            "ego_translation": [[0.0, 0.0, 0.0]], "ego_rotation": [IDENTITY],
            "sensor_translation": [[0.0, 0.0, 1.5]], "sensor_rotation": [ego_from_camera_rotation],
            "camera_intrinsic": [[[1000.0, 0.0, 800.0], [0.0, 1000.0, 450.0], [0.0, 0.0, 1.0]]],
        },
        schema_overrides={"ego_translation": pl.Array(pl.Float64, 3), "ego_rotation": pl.Array(pl.Float64, 4),
                          "sensor_translation": pl.Array(pl.Float64, 3), "sensor_rotation": pl.Array(pl.Float64, 4),
                          "camera_intrinsic": pl.Array(pl.Float64, (3, 3))},
    )
    return frames, annotations, samples


def boxes_by_token(frames, annotations, samples) -> dict[str, dict]:
    boxes = boxes_for_frames(frames, annotations, samples)
    return {row["annotation_token"]: row for row in boxes.iter_rows(named=True)}


def test_sweep_box_is_interpolated_for_instances_in_both_samples_and_dropped_when_only_in_previous():
    boxes = boxes_by_token(*small_tables(frame_timestamp=1250))
    assert set(boxes) == {"a-both-1", "a-new-1"}  # "gone" is not carried over from s0
    assert boxes["a-both-1"]["interpolated"] and not boxes["a-new-1"]["interpolated"]
    np.testing.assert_allclose(boxes["a-both-1"]["translation"], [12.5, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(boxes["a-both-1"]["rotation"], about_z(np.pi / 8), atol=1e-12)
    np.testing.assert_allclose(boxes["a-new-1"]["translation"], [30.0, -2.0, 0.0], atol=0)


def test_sweep_time_is_clamped_to_the_two_samples():
    before = boxes_by_token(*small_tables(frame_timestamp=500))
    after = boxes_by_token(*small_tables(frame_timestamp=2600))
    np.testing.assert_allclose(before["a-both-1"]["translation"], [10.0, 0.0, 0.0], atol=0)
    np.testing.assert_allclose(after["a-both-1"]["translation"], [20.0, 0.0, 0.0], atol=0)


def test_keyframe_and_first_sample_sweep_use_their_sample_boxes_unchanged():
    keyframe = boxes_by_token(*small_tables(frame_timestamp=1250, is_key_frame=True))
    first_sample_sweep = boxes_by_token(*small_tables(frame_timestamp=900, frame_sample="s0"))
    np.testing.assert_allclose(keyframe["a-both-1"]["translation"], [20.0, 0.0, 0.0], atol=0)
    assert not any(row["interpolated"] for row in keyframe.values())
    assert set(first_sample_sweep) == {"a-both-0", "a-gone-0"}
    assert not any(row["interpolated"] for row in first_sample_sweep.values())


def test_duplicate_instance_in_previous_sample_gives_one_box_from_the_last_like_devkit_dict():
    frames, annotations, samples = small_tables(frame_timestamp=1500)
    duplicate = annotations.filter(pl.col("token") == "a-both-0").with_columns(
        pl.lit("a-both-0-dup").alias("token"), pl.lit([14.0, 0.0, 0.0], dtype=pl.Array(pl.Float64, 3)).alias("translation")
    )
    boxes = boxes_for_frames(frames, pl.concat([annotations, duplicate]), samples)
    assert boxes.height == 2
    both = boxes.filter(pl.col("annotation_token") == "a-both-1")
    np.testing.assert_allclose(both["translation"].to_numpy()[0], [17.0, 0.0, 0.0], atol=1e-12)


def test_missing_previous_sample_is_an_error_not_silently_uninterpolated_boxes():
    frames, annotations, samples = small_tables(frame_timestamp=1250)
    with pytest.raises(ValueError, match="'s0'") as error:
        boxes_for_frames(frames, annotations, samples.filter(pl.col("token") == "s1"))
    # the message says what to pass, not only what is missing
    assert str(error.value) == ("samples lacks sample 's0' needed for frame 'f'; pass the sample table rows of the "
                                "frames' samples and of their previous samples")


def test_frame_boxes_as_a_dataframe_hold_every_box_under_its_documented_column():
    """`boxes_for_frames` (`FrameBoxes.to_polars`): the columns its docstring names, in that order and type, each
    holding the values of the hand-written tables (a keyframe: the boxes of s1 as written)."""
    frames, annotations, samples = small_tables(frame_timestamp=2000, is_key_frame=True)
    boxes = boxes_for_frames(frames, annotations, samples)
    assert boxes.columns == ["frame_index", "frame_token", "annotation_token", "instance_token", "category_name",
                             "translation", "size", "rotation", "interpolated"]
    assert boxes.schema["frame_index"] == pl.UInt32 and boxes.schema["interpolated"] == pl.Boolean
    assert all(boxes.schema[c] == pl.String for c in ("frame_token", "annotation_token", "instance_token",
                                                      "category_name"))
    written = {r["token"]: r for r in annotations.iter_rows(named=True)}
    assert boxes["annotation_token"].to_list() == ["a-both-1", "a-new-1"]
    for row in boxes.iter_rows(named=True):
        source = written[row["annotation_token"]]
        assert (row["frame_index"], row["frame_token"], row["interpolated"]) == (0, "f", False)
        assert (row["instance_token"], row["category_name"]) == (source["instance_token"], source["category_name"])
        assert [row[c] for c in ("translation", "size", "rotation")] == [source[c] for c in ("translation", "size",
                                                                                              "rotation")]


def test_box_straight_ahead_projects_around_the_principal_point():
    frames, annotations, samples = small_tables(frame_timestamp=2000, is_key_frame=True)
    projected = project_boxes(frames, annotations, samples, visibility="all")
    assert list(projected.annotation_token) == ["a-both-1", "a-new-1"]
    both = projected.take(projected.annotation_token == "a-both-1")
    # Centre 20 m ahead, 1.5 m below the camera: u = 800, v = 450 + 1000 * 1.5 / 20.
    center_px = both.corners_px[0].mean(axis=0)
    np.testing.assert_allclose(both.center_camera_m[0], [0.0, 1.5, 20.0], atol=1e-12)
    np.testing.assert_allclose(center_px[0], 800.0, atol=1e-9)
    assert both.distance_m[0] == pytest.approx(np.hypot(1.5, 20.0))
    table = projected.to_polars()
    assert table.height == 2 and table.schema["corners_px"] == pl.Array(pl.Float64, (8, 2))


def test_box_behind_the_camera_is_kept_only_without_visibility_filter():
    frames, annotations, samples = small_tables(frame_timestamp=2000, is_key_frame=True)
    frames = frames.with_columns(pl.lit([0.0, 0.0, 0.0, 1.0], dtype=pl.Array(pl.Float64, 4)).alias("ego_rotation"))
    assert len(project_boxes(frames, annotations, samples, visibility="any")) == 0
    behind = project_boxes(frames, annotations, samples, visibility="none")
    assert len(behind) == 2 and not behind.in_front.any() and not behind.visible.any()


def test_frames_without_intrinsic_get_no_boxes_and_unknown_visibility_is_rejected():
    frames, annotations, samples = small_tables(frame_timestamp=2000, is_key_frame=True)
    lidar = frames.with_columns(pl.lit(None, dtype=pl.Array(pl.Float64, (3, 3))).alias("camera_intrinsic"),
                                pl.lit("lidar").alias("token"))
    projected = project_boxes(pl.concat([lidar, frames]), annotations, samples, visibility="none")
    assert set(projected.frame_token) == {"f"} and set(projected.frame_index) == {1}
    empty = project_boxes(lidar, annotations, samples, visibility="none")
    assert empty.corners_px.shape == (0, 8, 2) and empty.to_polars().height == 0
    with pytest.raises(ValueError, match="visibility"):
        project_boxes(frames, annotations, samples, visibility="some")


def test_projected_boxes_as_a_dataframe_hold_every_field_under_its_name_and_type():
    """`ProjectedBoxes.to_polars`: one column per field, named as the field, with the documented dtype, holding
    the arrays' values (a box straddling the near plane, so both visibility flags vary)."""
    import dataclasses

    frames, annotations, samples = small_tables(frame_timestamp=2000, is_key_frame=True)
    projected = project_boxes(frames, annotations, samples, visibility="none")
    df = projected.to_polars()
    fields = [f.name for f in dataclasses.fields(projected)]
    assert fields[0] == "cuboids"  # the boxes, as columns translation, size, rotation after the category
    names = [*fields[1:6], *fields[6:]]
    assert df.columns == [*fields[1:6], "translation", "size", "rotation", *fields[6:]] and df.height == len(projected) > 0
    for column, values in (("translation", projected.translation_m), ("size", projected.size_wlh_m),
                           ("rotation", projected.rotation_wxyz)):
        assert df.schema[column] == pl.Array(pl.Float64, values.shape[1])
        np.testing.assert_array_equal(df[column].to_numpy(), values, err_msg=column)
    dtypes = {"frame_index": pl.Int64, "interpolated": pl.Boolean, "in_front": pl.Boolean, "visible": pl.Boolean,
              "distance_m": pl.Float64, "corners_camera_m": pl.Array(pl.Float64, (8, 3)),
              "corners_px": pl.Array(pl.Float64, (8, 2)), "depths": pl.Array(pl.Float64, 8),
              "corner_visible": pl.Array(pl.Boolean, 8), "center_ego_m": pl.Array(pl.Float64, 3),
              "center_camera_m": pl.Array(pl.Float64, 3)}
    for name in names:
        assert df.schema[name] == dtypes.get(name, pl.String), name
        values = getattr(projected, name)
        column = df[name].to_numpy() if df.schema[name] != pl.String else np.array(df[name].to_list())
        np.testing.assert_array_equal(column.reshape(values.shape), values, err_msg=name)


def test_depth_limits_are_strict_like_the_devkit():
    """devkit box_in_image: a corner counts as visible only at depth > 1 m and a box needs every corner at
    depth > 0.1 m. Boxes whose back faces lie exactly at 1.0 m and at 0.1 m (exact in floating point: the
    camera looks along ego x with a rotation of 0/+-1 entries) sit on those limits."""
    frames, annotations, samples = small_tables(frame_timestamp=2000, is_key_frame=True)
    annotations = annotations.filter(pl.col("sample_token") == "s1").head(2).with_columns(
        translation=pl.Series([[1.5, 0.0, 1.5], [0.225, 0.0, 1.5]], dtype=pl.Array(pl.Float64, 3)),  # 0.225 - 0.125 == 0.1
        size=pl.Series([[0.5, 1.0, 0.5], [0.5, 0.25, 0.5]], dtype=pl.Array(pl.Float64, 3)),
        rotation=pl.Series([IDENTITY, IDENTITY], dtype=pl.Array(pl.Float64, 4)))
    projected = project_boxes(frames, annotations, samples, visibility="none")
    at_one, at_tenth = (np.flatnonzero(projected.annotation_token == t)[0] for t in annotations["token"])
    np.testing.assert_array_equal(np.sort(np.unique(projected.depths[at_one])), [1.0, 2.0])
    np.testing.assert_array_equal(np.sort(np.unique(projected.depths[at_tenth])), [0.1, 0.35])
    assert (projected.corner_visible[at_one] == (projected.depths[at_one] == 2.0)).all()  # 1.0 m: not visible
    assert projected.in_front[at_one] and not projected.in_front[at_tenth]  # 0.1 m: not in front
    kept = project_boxes(frames, annotations, samples, visibility="any")
    assert set(kept.annotation_token) == {annotations["token"][0]}
