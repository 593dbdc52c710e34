"""The MCAP export against nuscenes-devkit: boxes (keyframes and every interpolated camera frame) equal
`NuScenes.get_boxes`, transforms equal the devkit's ego_pose and calibrated_sensor records, point clouds equal
`LidarPointCloud.from_file` / `RadarPointCloud.from_file`; on the synthetic dataset (every sweep file present) and
on a real scene of the extract (keyframe files only: the sweeps' messages are left out and named)."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from pyquaternion import Quaternion

from mcap_files import point_fields, read_messages, validate
from nuparquet.mcap import McapOptions, export_mcap

SYNTH_VERSION = "v1.0-synth"
REAL_SCENE = "scene-0916"


def _boxes_equal_devkit(nusc, update, sample_data_token: str) -> int:
    """Assert the SceneUpdate's cubes are the devkit's get_boxes(sample_data_token); returns how many."""
    expected = {nusc.get("sample_annotation", box.token)["instance_token"]: box
                for box in nusc.get_boxes(sample_data_token)}
    entities = {e.id: e for e in update.entities}
    assert set(entities) == set(expected)
    for instance, box in expected.items():
        cube = entities[instance].cubes[0]
        position, q = cube.pose.position, cube.pose.orientation
        np.testing.assert_allclose([position.x, position.y, position.z], box.center, rtol=0, atol=1e-9)
        np.testing.assert_allclose([q.w, q.x, q.y, q.z], box.orientation.elements, rtol=0, atol=1e-12)
        assert (cube.size.x, cube.size.y, cube.size.z) == (box.wlh[1], box.wlh[0], box.wlh[2])
        meta = {kv.key: kv.value for kv in entities[instance].metadata}
        assert meta["annotation_token"] == box.token and meta["category"] == box.name
    return len(expected)


def _check_transforms(nusc, messages) -> int:
    """Every /tf message against the devkit's records of the sample_data at that time and channel."""
    by_key = {}
    for record in nusc.sample_data:
        by_key[(record["channel"], record["timestamp"])] = record
    for item in messages["/tf"]:
        ego, sensor = item.message.transforms
        record = by_key[(sensor.child_frame_id, item.log_time_ns // 1000)]
        pose = nusc.get("ego_pose", record["ego_pose_token"])
        calibration = nusc.get("calibrated_sensor", record["calibrated_sensor_token"])
        for transform, source in ((ego, pose), (sensor, calibration)):
            t, r = transform.translation, transform.rotation
            assert [t.x, t.y, t.z] == source["translation"]
            expected = Quaternion(source["rotation"]).normalised.elements
            np.testing.assert_allclose([r.w, r.x, r.y, r.z], expected, rtol=0, atol=1e-15)
    return len(messages["/tf"])


@pytest.fixture(scope="module")
def synth_nusc(devkit, synth_root):
    return devkit.NuScenes(version=SYNTH_VERSION, dataroot=str(synth_root), verbose=False)


@pytest.fixture(scope="module")
def synth_messages(synth_points_out, tmp_path_factory):
    out = tmp_path_factory.mktemp("mcap-devkit") / "scene.mcap"
    export_mcap(synth_points_out, "scene-0002", out)
    return read_messages(out)


def _frames_of(nusc, scene_name: str, channel: str) -> list[dict]:
    scene = next(s for s in nusc.scene if s["name"] == scene_name)
    samples = {s["token"] for s in nusc.sample if s["scene_token"] == scene["token"]}
    return sorted((r for r in nusc.sample_data if r["sample_token"] in samples and r["channel"] == channel),
                  key=lambda r: r["timestamp"])


def test_synthetic_boxes_equal_devkit_get_boxes_at_keyframes_and_every_camera_frame(synth_nusc, synth_messages):
    updates = synth_messages["/markers/annotations"]
    by_time = {u.log_time_ns // 1000: u.message for u in updates}
    lidar = [r for r in _frames_of(synth_nusc, "scene-0002", "LIDAR_TOP") if r["is_key_frame"]]
    sweeps = [r for r in _frames_of(synth_nusc, "scene-0002", "CAM_FRONT") if not r["is_key_frame"]]
    assert len(updates) == len(lidar) + len(sweeps)
    boxes = sum(_boxes_equal_devkit(synth_nusc, by_time[r["timestamp"]], r["token"]) for r in lidar + sweeps)
    interpolated = sum(1 for u in updates for e in u.message.entities
                       if {kv.key: kv.value for kv in e.metadata}["interpolated"] == "true")
    assert boxes > 100 and interpolated > 50


def test_synthetic_transforms_equal_devkit_records(synth_nusc, synth_messages):
    assert _check_transforms(synth_nusc, synth_messages) == sum(
        len(_frames_of(synth_nusc, "scene-0002", c)) for c in {r["channel"] for r in synth_nusc.sample_data})


def test_synthetic_point_clouds_equal_devkit_from_file(synth_nusc, synth_messages, synth_root):
    from nuscenes.utils.data_classes import LidarPointCloud, RadarPointCloud

    lidar = _frames_of(synth_nusc, "scene-0002", "LIDAR_TOP")
    for item, record in zip(synth_messages["/LIDAR_TOP"], lidar, strict=True):
        points = point_fields(item.message)
        expected = LidarPointCloud.from_file(str(synth_root / record["filename"])).points
        got = np.stack([points[n] for n in ("x", "y", "z", "intensity")])
        assert np.array_equal(got.view(np.uint32), expected.view(np.uint32))
    RadarPointCloud.disable_filters()
    try:
        for channel in ("RADAR_FRONT", "RADAR_BACK_LEFT"):
            for item, record in zip(synth_messages[f"/{channel}"], _frames_of(synth_nusc, "scene-0002", channel),
                                    strict=True):
                points = point_fields(item.message)
                expected = RadarPointCloud.from_file(str(synth_root / record["filename"])).points
                got = np.stack([points[n].astype(np.float64) for n in points.dtype.names])
                assert np.array_equal(got, expected)
    finally:
        RadarPointCloud.default_filters()


@pytest.fixture(scope="module")
def real_nusc(devkit, extract_root):
    from conftest import EXTRACT_VERSION

    return devkit.NuScenes(version=EXTRACT_VERSION, dataroot=str(extract_root), verbose=False)


@pytest.fixture(scope="module")
def real_export(extract_out, tmp_path_factory):
    out = tmp_path_factory.mktemp("mcap-real") / f"{REAL_SCENE}.mcap"
    result = export_mcap(extract_out, REAL_SCENE, out)
    return result, read_messages(out)


def test_real_scene_carries_every_keyframe_file_and_names_the_missing_sweeps(real_nusc, real_export, extract_root):
    result, messages = real_export
    validate(result.out)
    channels = sorted({r["channel"] for r in real_nusc.sample_data})
    expected_missing = []
    for channel in channels:
        frames = _frames_of(real_nusc, REAL_SCENE, channel)
        present = [r for r in frames if (extract_root / r["filename"]).is_file()]
        # named under the dataroot the manifest records, resolved (../shared may be a link)
        expected_missing += [str(extract_root.resolve() / r["filename"]) for r in frames if r not in present]
        assert present == [r for r in frames if r["is_key_frame"]]  # the extract has keyframe files only
        if channel.startswith("CAM"):
            images = messages[f"/{channel}/image_rect_compressed"]
            assert [m.message.data for m in images] == [(extract_root / r["filename"]).read_bytes() for r in present]
            assert len(messages[f"/{channel}/camera_info"]) == len(frames)
        else:
            assert [m.log_time_ns // 1000 for m in messages[f"/{channel}"]] == [r["timestamp"] for r in present]
    assert sorted(result.missing) == sorted(expected_missing)
    images = sum((extract_root / r["filename"]).stat().st_size for c in channels if c.startswith("CAM")
                 for r in _frames_of(real_nusc, REAL_SCENE, c) if r["is_key_frame"])
    # JPEGs do not compress: the file is about the size of the sensor files it carries
    assert result.sensor_bytes > images and images < result.bytes < 1.1 * result.sensor_bytes


def test_real_scene_boxes_and_transforms_equal_the_devkit(real_nusc, real_export):
    _, messages = real_export
    by_time = {u.log_time_ns // 1000: u.message for u in messages["/markers/annotations"]}
    lidar = [r for r in _frames_of(real_nusc, REAL_SCENE, "LIDAR_TOP") if r["is_key_frame"]]
    sweeps = [r for r in _frames_of(real_nusc, REAL_SCENE, "CAM_FRONT") if not r["is_key_frame"]]
    assert len(by_time) == len(lidar) + len(sweeps) == len(messages["/markers/annotations"])
    boxes = sum(_boxes_equal_devkit(real_nusc, by_time[r["timestamp"]], r["token"]) for r in lidar + sweeps)
    assert boxes > 5000
    assert _check_transforms(real_nusc, messages) == len(
        [r for r in real_nusc.sample_data if r["sample_token"] in {s["token"] for s in real_nusc.sample
                                                                   if real_nusc.get("scene", s["scene_token"])["name"]
                                                                   == REAL_SCENE}])


def test_real_scene_can_bus_topics_are_the_expansion_files(real_export, extract_root):
    import json

    _, messages = real_export
    topics = Counter(t.split("/")[2] for t in messages if t.startswith("/can_bus/"))
    assert set(topics) == {"ms_imu", "pose", "steeranglefeedback", "vehicle_monitor"}
    for message in topics:
        records = json.loads((extract_root / "can_bus" / f"{REAL_SCENE}_{message}.json").read_text())
        assert [m.message for m in messages[f"/can_bus/{message}"]] == sorted(records, key=lambda r: r["utime"])
