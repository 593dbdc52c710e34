"""Channel facts from the data (`nuparquet.channels`, `Dataset.channels`): reference lidar, camera set, layout."""

from __future__ import annotations

import json
import shutil

import numpy as np

import nuparquet
from conftest import SYNTH_VERSION
from nuparquet import channels

NUSCENES_CAMERAS = ["CAM_BACK", "CAM_BACK_LEFT", "CAM_BACK_RIGHT", "CAM_FRONT", "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT"]


def yaw_quaternion(yaw_deg: float) -> list[float]:
    """ego_from_camera rotation of a level camera (optical axis z) looking `yaw_deg` left of ego x."""
    half = np.deg2rad(yaw_deg) / 2
    about_z = np.array([np.cos(half), 0.0, 0.0, np.sin(half)])
    optical = np.array([0.5, -0.5, 0.5, -0.5])  # camera z -> ego x, camera x -> ego -y
    w0, x0, y0, z0 = about_z
    w1, x1, y1, z1 = optical
    return [w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1, w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
            w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1, w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1]


def test_camera_yaw_reads_the_optical_axis_heading():
    yaws = channels.camera_yaw(np.array([yaw_quaternion(a) for a in (0.0, 55.0, -110.0, 180.0)]))
    np.testing.assert_allclose(np.rad2deg(yaws), [0.0, 55.0, -110.0, 180.0], atol=1e-9)


def test_reference_lidar_prefers_lidar_top_else_the_first_lidar_by_name():
    assert channels.reference_lidar(["LIDAR_FRONT_LEFT", "LIDAR_TOP", "CAM_FRONT"],
                                    ["lidar", "lidar", "camera"]) == "LIDAR_TOP"
    assert channels.reference_lidar(["LIDAR_Z", "LIDAR_B", "RADAR_A"], ["lidar", "lidar", "radar"]) == "LIDAR_B"
    assert channels.reference_lidar(["CAM_FRONT"], ["camera"]) is None


def test_lyft_cameras_are_laid_out_front_row_of_four_over_back_row_of_three():
    cameras = ["CAM_BACK", "CAM_FRONT_ZOOMED", "CAM_FRONT_LEFT", "CAM_BACK_RIGHT", "CAM_FRONT", "CAM_BACK_LEFT",
               "CAM_FRONT_RIGHT"]
    yaw = {"CAM_FRONT": 0.0, "CAM_FRONT_ZOOMED": 0.3, "CAM_FRONT_LEFT": 60.0, "CAM_FRONT_RIGHT": -60.0,
           "CAM_BACK": 180.0, "CAM_BACK_LEFT": 120.0, "CAM_BACK_RIGHT": -120.0}
    layout = channels.camera_layout(cameras, [np.deg2rad(yaw[c]) for c in cameras])
    assert layout == (("CAM_FRONT_LEFT", "CAM_FRONT_ZOOMED", "CAM_FRONT", "CAM_FRONT_RIGHT"),
                      ("CAM_BACK_LEFT", "CAM_BACK", "CAM_BACK_RIGHT"))


def test_cameras_without_front_or_back_in_their_names_are_laid_out_by_yaw():
    cameras = ["cam_a", "cam_b", "cam_c", "cam_d"]
    yaws = np.deg2rad([170.0, 10.0, -30.0, -150.0])  # a: back left, b: front left, c: front right, d: back right
    assert channels.camera_layout(cameras, yaws) == (("cam_b", "cam_c"), ("cam_a", "cam_d"))


def test_without_yaws_names_put_left_before_plain_before_right_whatever_they_sort_as():
    """Names alone (no calibrated yaw): LEFT, then a name saying neither side, then RIGHT, in each row. The wide
    cameras' names sort after the RIGHT ones (W > R), so an order falling back on the names would put them last."""
    cameras = ["CAM_FRONT_RIGHT", "CAM_BACK_WIDE", "CAM_FRONT_WIDE", "CAM_BACK_LEFT", "CAM_BACK_RIGHT", "CAM_FRONT_LEFT"]
    assert channels.camera_layout(cameras) == (("CAM_FRONT_LEFT", "CAM_FRONT_WIDE", "CAM_FRONT_RIGHT"),
                                               ("CAM_BACK_LEFT", "CAM_BACK_WIDE", "CAM_BACK_RIGHT"))


def test_default_camera_is_cam_front_else_the_first_front_camera():
    assert channels.default_camera(NUSCENES_CAMERAS) == "CAM_FRONT"
    assert channels.default_camera(["cam_a", "cam_b"], (("cam_b",), ("cam_a",))) == "cam_b"


def test_channel_facts_group_sensors_and_lay_out_cameras():
    sensors = NUSCENES_CAMERAS + ["LIDAR_TOP", "RADAR_FRONT", "RADAR_BACK_LEFT"]
    modalities = ["camera"] * 6 + ["lidar", "radar", "radar"]
    facts = channels.channel_facts(sensors, modalities)
    assert facts == {
        "reference_lidar": "LIDAR_TOP",
        "cameras": NUSCENES_CAMERAS,
        "camera_layout": [["CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_RIGHT"],
                          ["CAM_BACK_LEFT", "CAM_BACK", "CAM_BACK_RIGHT"]],
        "lidars": ["LIDAR_TOP"],
        "radars": ["RADAR_BACK_LEFT", "RADAR_FRONT"],
    }
    json.dumps(facts)  # goes into manifest.json as it is


def test_dataset_channels_come_from_the_manifest_or_else_from_the_data(synth_root, synth_out, tmp_path):
    copy = tmp_path / "out"
    shutil.copytree(synth_out, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest.pop("channels", None)  # an output written before channels were recorded
    (copy / "manifest.json").write_text(json.dumps(manifest))
    computed = nuparquet.open(copy).channels
    # The synthetic sensor table, read as JSON: the expectation does not go through the converter.
    sensor = json.loads((synth_root / SYNTH_VERSION / "sensor.json").read_text())
    assert computed["cameras"] == sorted(s["channel"] for s in sensor if s["modality"] == "camera")
    assert computed["radars"] == sorted(s["channel"] for s in sensor if s["modality"] == "radar")
    assert computed["reference_lidar"] == "LIDAR_TOP" and computed["lidars"] == ["LIDAR_TOP"]
    assert computed["camera_layout"] == [["CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_RIGHT"],
                                         ["CAM_BACK_LEFT", "CAM_BACK", "CAM_BACK_RIGHT"]]

    manifest["channels"] = {"reference_lidar": None, "cameras": ["X"], "camera_layout": [["X"]], "lidars": [],
                            "radars": []}
    (copy / "manifest.json").write_text(json.dumps(manifest))
    assert nuparquet.open(copy).channels == manifest["channels"]


def test_an_output_without_channels_or_sensor_tables_takes_its_channels_from_the_frames(synth_root, synth_out,
                                                                                       tmp_path):
    """channels_of_dataset's last resort: no "channels" record and no tables/sensor in the manifest, so the channels
    and modalities come from `frames`; the names lay the cameras out. The expectation: the channels of the source
    sample_data records, read as JSON through calibrated_sensor and sensor."""
    copy = tmp_path / "out"
    shutil.copytree(synth_out, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest.pop("channels", None)
    del manifest["datasets"]["tables/sensor"]
    (copy / "manifest.json").write_text(json.dumps(manifest))
    source = synth_root / SYNTH_VERSION
    sensor = {s["token"]: s for s in json.loads((source / "sensor.json").read_text())}
    sensor_of = {c["token"]: sensor[c["sensor_token"]] for c in json.loads((source / "calibrated_sensor.json").read_text())}
    recorded = {(sensor_of[d["calibrated_sensor_token"]]["channel"], sensor_of[d["calibrated_sensor_token"]]["modality"])
                for d in json.loads((source / "sample_data.json").read_text())}
    computed = nuparquet.open(copy).channels
    for modality, key in (("camera", "cameras"), ("lidar", "lidars"), ("radar", "radars")):
        assert computed[key] == sorted(c for c, m in recorded if m == modality), key
    assert computed["cameras"] == NUSCENES_CAMERAS and computed["reference_lidar"] == "LIDAR_TOP"
    assert computed["camera_layout"] == [["CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_RIGHT"],
                                         ["CAM_BACK_LEFT", "CAM_BACK", "CAM_BACK_RIGHT"]]


def test_a_rig_with_one_camera_name_that_says_neither_front_nor_back_is_laid_out_by_yaw():
    """Names decide only when every camera's name says FRONT or BACK: one unknown name (a side camera looking
    backwards) puts the whole rig on yaw, which sends that camera to the back row, in yaw order."""
    cameras = ["CAM_FRONT", "CAM_BACK", "CAM_SIDE_X", "CAM_FRONT_LEFT"]
    yaws = [0.0, np.pi, np.deg2rad(170.0), np.deg2rad(55.0)]
    assert channels.camera_layout(cameras, yaws) == (("CAM_FRONT_LEFT", "CAM_FRONT"), ("CAM_SIDE_X", "CAM_BACK"))
    # the same camera looking forward-right joins the front row, right of CAM_FRONT (decreasing yaw)
    yaws[2] = np.deg2rad(-60.0)
    assert channels.camera_layout(cameras, yaws) == (("CAM_FRONT_LEFT", "CAM_FRONT", "CAM_SIDE_X"), ("CAM_BACK",))
    # without yaws the names alone decide: the unknown name is neither BACK nor LEFT/RIGHT, so front, middle
    assert channels.camera_layout(cameras) == (("CAM_FRONT_LEFT", "CAM_FRONT", "CAM_SIDE_X"), ("CAM_BACK",))


def test_default_camera_without_cam_front_or_a_layout_is_the_first_camera_named():
    assert channels.default_camera(["CAM_X", "CAM_Y"]) == "CAM_X"
    assert channels.default_camera(["CAM_X", "CAM_FRONT"]) == "CAM_FRONT"
    assert channels.default_camera(["CAM_X", "CAM_Y"], (("CAM_Y",), ("CAM_X",))) == "CAM_Y"
    assert channels.default_camera([]) is None


def test_an_output_without_channels_whose_camera_names_are_partly_unknown_lays_them_out_by_calibrated_yaw(
        synth_root, synth_out, tmp_path):
    """channels_of_dataset (an output written before the manifest recorded channels): CAM_BACK_LEFT renamed
    CAM_SIDE_X in tables/sensor, so the names no longer decide; its calibration looks back-left, so the layout must
    put it in the back row, left of CAM_BACK (its yaw from calibrated_sensor, read here with pyquaternion)."""
    import polars as pl
    from pyquaternion import Quaternion

    copy = tmp_path / "out"
    shutil.copytree(synth_out, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest.pop("channels", None)
    (copy / "manifest.json").write_text(json.dumps(manifest))
    sensor_file = next((copy / "tables" / "sensor").glob("*.parquet"))
    sensors = pl.read_parquet(sensor_file)
    sensors.with_columns(pl.col("channel").replace("CAM_BACK_LEFT", "CAM_SIDE_X")).write_parquet(sensor_file)

    # The expectation from the source JSON: each camera's optical axis (camera z) in the ego frame, as a heading.
    sensor = {s["token"]: s for s in json.loads((synth_root / SYNTH_VERSION / "sensor.json").read_text())}
    axes: dict[str, list[np.ndarray]] = {}  # one per calibration (a rig per log, a little apart)
    for cs in json.loads((synth_root / SYNTH_VERSION / "calibrated_sensor.json").read_text()):
        if sensor[cs["sensor_token"]]["modality"] == "camera":
            name = sensor[cs["sensor_token"]]["channel"].replace("CAM_BACK_LEFT", "CAM_SIDE_X")
            axes.setdefault(name, []).append(np.asarray(Quaternion(cs["rotation"]).rotate([0.0, 0.0, 1.0])))
    assert all(min(a @ b for a in v for b in v) > np.cos(np.deg2rad(10)) for v in axes.values())
    mean_axis = {name: np.mean(v, axis=0) for name, v in axes.items()}
    heading = {name: float(np.degrees(np.arctan2(a[1], a[0]))) for name, a in mean_axis.items()}
    assert 90 < heading["CAM_SIDE_X"] < 180  # looking back-left
    front = sorted((c for c in heading if abs(heading[c]) <= 90), key=lambda c: -heading[c])  # left to right
    back = sorted((c for c in heading if abs(heading[c]) > 90), key=lambda c: heading[c] % 360)
    assert [front, back] == [["CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_RIGHT"],
                             ["CAM_SIDE_X", "CAM_BACK", "CAM_BACK_RIGHT"]]

    computed = nuparquet.open(copy).channels
    assert computed["cameras"] == sorted(heading)
    assert computed["camera_layout"] == [front, back]
