"""`nuparquet export-mcap`: one scene of the synthetic dataset (images, lidar and radar keyframes and sweeps with
lidarseg/panoptic labels, CAN bus, map) read back with the mcap reader, every message decoded and compared with
what the source files and JSON tables say (never with our own Parquet, except for the stored transform matrices
the issue names)."""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import shapely
from pyquaternion import Quaternion

from mcap_files import point_fields, read_messages, stamp_us, validate
import nuparquet
from nuparquet.cli.main import main
from nuparquet.errors import InputError, UsageError
from nuparquet.mcap import McapOptions, export_mcap

VERSION = "v1.0-synth"
SCENE = "scene-0001"  # has CAN bus data (the generator leaves the last scene without)
CAMERAS = ("CAM_FRONT", "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT", "CAM_BACK", "CAM_BACK_LEFT", "CAM_BACK_RIGHT")
RADARS = ("RADAR_FRONT", "RADAR_FRONT_LEFT", "RADAR_FRONT_RIGHT", "RADAR_BACK_LEFT", "RADAR_BACK_RIGHT")


class Tables:
    """The JSON tables of the synthetic dataroot, joined by hand: the independent expectations."""

    def __init__(self, root: Path, scene: str):
        def table(name):
            return json.loads((root / VERSION / f"{name}.json").read_text())

        self.root = root
        scene_record = next(s for s in table("scene") if s["name"] == scene)
        self.scene = scene_record
        self.samples = [s for s in table("sample") if s["scene_token"] == scene_record["token"]]
        sample_tokens = {s["token"] for s in self.samples}
        channel_of_sensor = {s["token"]: s["channel"] for s in table("sensor")}
        self.calibration = {c["token"]: c for c in table("calibrated_sensor")}
        self.channel_of_calibration = {t: channel_of_sensor[c["sensor_token"]] for t, c in self.calibration.items()}
        self.ego_pose = {e["token"]: e for e in table("ego_pose")}
        self.sample_data = [r for r in table("sample_data") if r["sample_token"] in sample_tokens]
        for record in self.sample_data:
            record["channel"] = self.channel_of_calibration[record["calibrated_sensor_token"]]
        self.annotations = [a for a in table("sample_annotation") if a["sample_token"] in sample_tokens]
        instances = {i["token"]: i for i in table("instance")}
        categories = {c["token"]: c["name"] for c in table("category")}
        self.category_of_instance = {t: categories[i["category_token"]] for t, i in instances.items()}
        self.log = next(lg for lg in table("log") if lg["token"] == scene_record["log_token"])

    def frames(self, channel: str) -> list[dict]:
        return sorted((r for r in self.sample_data if r["channel"] == channel), key=lambda r: r["timestamp"])

    def can_bus(self, message: str) -> list[dict]:
        return json.loads((self.root / "can_bus" / f"{self.scene['name']}_{message}.json").read_text())


@pytest.fixture(scope="module")
def tables(synth_root) -> Tables:
    return Tables(synth_root, SCENE)


@pytest.fixture(scope="module")
def exported(synth_points_out, tmp_path_factory):
    """scene-0001 exported with the defaults, its progress events, and every message decoded."""
    out = tmp_path_factory.mktemp("mcap") / f"{SCENE}.mcap"
    events = []
    result = export_mcap(synth_points_out, SCENE, out, on_progress=events.append)
    return result, events, read_messages(out)


def test_the_file_passes_the_readers_validation(exported):
    result, _, messages = exported
    facts = validate(result.out)
    assert facts["compression"] == {"zstd"}
    assert len(facts["chunks"]) > 1  # chunked, not one blob
    assert {topic: len(items) for topic, items in messages.items()} == result.messages
    assert result.out.stat().st_size == result.bytes
    assert not list(result.out.parent.glob(".*partial*"))


def test_every_topic_holds_one_message_per_row_of_the_scene(exported, tables):
    _, _, messages = exported
    counts = {topic: len(items) for topic, items in messages.items()}
    expected = {"/tf": len(tables.sample_data), "/map": 1}
    for camera in CAMERAS:
        n = len(tables.frames(camera))
        expected |= {f"/{camera}/image_rect_compressed": n, f"/{camera}/camera_info": n}
    for channel in ("LIDAR_TOP", *RADARS):
        expected[f"/{channel}"] = len(tables.frames(channel))
    sweeps = [r for r in tables.frames("CAM_FRONT") if not r["is_key_frame"]]
    expected["/markers/annotations"] = len(tables.samples) + len(sweeps)
    for message in ("ms_imu", "pose", "steeranglefeedback", "vehicle_monitor", "zoe_veh_info"):
        expected[f"/can_bus/{message}"] = len(tables.can_bus(message))
    assert counts == expected
    assert all(n > 0 for n in counts.values())
    # sequence numbers count each topic's messages from 1
    for items in messages.values():
        assert [m.sequence for m in items] == list(range(1, len(items) + 1))


def test_messages_are_in_log_time_order_with_the_datas_exact_microseconds(exported, tables):
    result, _, messages = exported
    from mcap_files import log_times

    times = log_times(result.out)
    assert times == sorted(times) and len(times) == sum(result.messages.values())
    for camera in CAMERAS:
        expected = [r["timestamp"] for r in tables.frames(camera)]
        items = messages[f"/{camera}/image_rect_compressed"]
        assert [m.log_time_ns for m in items] == [t * 1000 for t in expected]
        assert [m.publish_time_ns for m in items] == [t * 1000 for t in expected]
        assert [stamp_us(m.message.timestamp) for m in items] == expected
    for item in messages["/tf"]:
        assert all(stamp_us(t.timestamp) * 1000 == item.log_time_ns for t in item.message.transforms)


def test_image_bytes_are_the_files_and_calibrations_their_intrinsics(exported, tables):
    _, _, messages = exported
    for camera in CAMERAS:
        frames = tables.frames(camera)
        images = messages[f"/{camera}/image_rect_compressed"]
        assert [m.message.data for m in images] == [(tables.root / r["filename"]).read_bytes() for r in frames]
        assert {m.message.format for m in images} == {"jpeg"} and {m.message.frame_id for m in images} == {camera}
        assert {m.schema_name for m in images} == {"foxglove.CompressedImage"}
        for item, record in zip(messages[f"/{camera}/camera_info"], frames):
            K = np.array(tables.calibration[record["calibrated_sensor_token"]]["camera_intrinsic"])
            info = item.message
            assert np.array_equal(np.reshape(info.K, (3, 3)), K)
            assert np.array_equal(np.reshape(info.P, (3, 4)), np.c_[K, np.zeros(3)])
            assert np.array_equal(np.reshape(info.R, (3, 3)), np.eye(3))
            assert info.distortion_model == "plumb_bob" and list(info.D) == [0.0] * 5  # rectified images
            assert (info.width, info.height, info.frame_id) == (record["width"], record["height"], camera)


def _matrix(translation, rotation) -> np.ndarray:
    """4x4 from a Foxglove Vector3 and Quaternion, with pyquaternion (the devkit's maths)."""
    matrix = np.eye(4)
    matrix[:3, :3] = Quaternion(rotation.w, rotation.x, rotation.y, rotation.z).rotation_matrix
    matrix[:3, 3] = (translation.x, translation.y, translation.z)
    return matrix


def test_transforms_equal_the_stored_matrices_and_the_poses(exported, synth_points_out, tables):
    _, _, messages = exported
    frames = (pl.scan_parquet(f"{synth_points_out}/frames/**/*.parquet").filter(pl.col("scene_name") == SCENE)
              .select("token", pl.col("channel").cast(pl.String), "timestamp", "global_from_ego", "ego_from_sensor")
              .collect())
    stored = {(c, t): (np.reshape(g, (4, 4)), np.reshape(e, (4, 4)))
              for c, t, g, e in zip(frames["channel"], frames["timestamp"], frames["global_from_ego"].to_list(),
                                    frames["ego_from_sensor"].to_list())}
    records = {(r["channel"], r["timestamp"]): r for r in tables.sample_data}
    seen = set()
    for item in messages["/tf"]:
        ego, sensor = item.message.transforms
        assert (ego.parent_frame_id, ego.child_frame_id, sensor.parent_frame_id) == ("map", "base_link", "base_link")
        key = (sensor.child_frame_id, item.log_time_ns // 1000)
        seen.add(key)
        global_from_ego, ego_from_sensor = stored[key]
        np.testing.assert_allclose(_matrix(ego.translation, ego.rotation), global_from_ego, rtol=0, atol=1e-9)
        np.testing.assert_allclose(_matrix(sensor.translation, sensor.rotation), ego_from_sensor, rtol=0, atol=1e-12)
        record = records[key]
        pose = tables.ego_pose[record["ego_pose_token"]]
        assert [ego.translation.x, ego.translation.y, ego.translation.z] == pose["translation"]
        calibration = tables.calibration[record["calibrated_sensor_token"]]
        assert [sensor.translation.x, sensor.translation.y, sensor.translation.z] == calibration["translation"]
    assert seen == set(records)  # every frame's transforms, once


def test_keyframe_boxes_are_the_annotations(exported, tables):
    _, _, messages = exported
    updates = {m.log_time_ns // 1000: m.message for m in messages["/markers/annotations"]}
    by_sample = defaultdict(list)
    for annotation in tables.annotations:
        by_sample[annotation["sample_token"]].append(annotation)
    for sample in tables.samples:
        update = updates[sample["timestamp"]]
        assert [d.type for d in update.deletions] == [1]  # ALL: the previous boxes go
        entities = {e.id: e for e in update.entities}
        annotations = by_sample[sample["token"]]
        assert len(entities) == len(annotations) > 0
        for annotation in annotations:
            entity = entities[annotation["instance_token"]]
            cube = entity.cubes[0]
            assert entity.frame_id == "map"
            assert [cube.pose.position.x, cube.pose.position.y, cube.pose.position.z] == annotation["translation"]
            q = cube.pose.orientation
            assert [q.w, q.x, q.y, q.z] == annotation["rotation"]
            w, l, h = annotation["size"]
            assert (cube.size.x, cube.size.y, cube.size.z) == (l, w, h)  # x along the heading: length
            category = tables.category_of_instance[annotation["instance_token"]]
            meta = {kv.key: kv.value for kv in entity.metadata}
            assert meta == {"category": category, "instance_token": annotation["instance_token"],
                            "annotation_token": annotation["token"], "interpolated": "false"}
            assert entity.texts[0].text == category
            assert stamp_us(entity.timestamp) == sample["timestamp"]


def test_interpolated_boxes_lie_between_their_keyframes(exported, tables):
    """Between two keyframes each box moves along the segment joining its two annotations (the exact devkit
    numbers are checked in tests/parity/test_mcap_devkit.py)."""
    _, _, messages = exported
    samples = sorted(tables.samples, key=lambda s: s["timestamp"])
    annotation_at = {(a["sample_token"], a["instance_token"]): a for a in tables.annotations}
    interpolated = 0
    for item in messages["/markers/annotations"]:
        t = item.log_time_ns // 1000
        after = next((s for s in samples if s["timestamp"] >= t), None)
        before = next((s for s in reversed(samples) if s["timestamp"] < t), None)
        if after is None or before is None or after["timestamp"] == t:
            continue
        amount = (t - before["timestamp"]) / (after["timestamp"] - before["timestamp"])
        for entity in item.message.entities:
            meta = {kv.key: kv.value for kv in entity.metadata}
            a0, a1 = annotation_at.get((before["token"], entity.id)), annotation_at[(after["token"], entity.id)]
            position = entity.cubes[0].pose.position
            expected = a1["translation"] if a0 is None else (
                np.array(a0["translation"]) + amount * (np.array(a1["translation"]) - np.array(a0["translation"])))
            np.testing.assert_allclose([position.x, position.y, position.z], expected, rtol=0, atol=1e-9)
            assert meta["interpolated"] == ("false" if a0 is None else "true")
            interpolated += a0 is not None
    assert interpolated > 20


def test_points_are_the_files_with_their_labels(exported, tables):
    _, _, messages = exported
    lidar = tables.frames("LIDAR_TOP")
    for item, record in zip(messages["/LIDAR_TOP"], lidar):
        points = point_fields(item.message)
        expected = np.fromfile(tables.root / record["filename"], dtype="<f4").reshape(-1, 5)
        assert points.dtype.names[:5] == ("x", "y", "z", "intensity", "ring")
        assert np.array_equal(np.stack([points[n] for n in points.dtype.names[:5]], axis=1), expected)
        assert item.message.frame_id == "LIDAR_TOP"
        if record["is_key_frame"]:  # labels exist for keyframes only
            seg = np.fromfile(tables.root / "lidarseg" / VERSION / f"{record['token']}_lidarseg.bin", dtype=np.uint8)
            panoptic = np.load(tables.root / "panoptic" / VERSION / f"{record['token']}_panoptic.npz")["data"]
            assert np.array_equal(points["lidarseg_label"], seg)
            assert np.array_equal(points["panoptic_label"], panoptic)
        else:
            assert len(points.dtype.names) == 5
    for radar in RADARS:
        for item, record in zip(messages[f"/{radar}"], tables.frames(radar)):
            raw = (tables.root / record["filename"]).read_bytes()
            data_start = raw.index(b"DATA binary\n") + len(b"DATA binary\n")
            header = raw[:data_start].decode()
            fields = next(line.split()[1:] for line in header.splitlines() if line.startswith("FIELDS"))
            count = int(next(line.split()[1] for line in header.splitlines() if line.startswith("POINTS")))
            stride = item.message.point_stride
            assert item.message.data == raw[data_start:data_start + count * stride]  # the PCD records as stored
            assert [f.name for f in item.message.fields] == fields


def test_points_read_from_the_files_are_the_same_messages(exported, synth_out, tables, tmp_path):
    """Without lidar_points/ and radar_points/ the points come from the files: the same bytes (lidar without the
    labels, which only the conversion adds). Without images, the sensor bytes carried are the point files' sizes."""
    _, _, messages = exported
    out = tmp_path / "files.mcap"
    result = export_mcap(synth_out, SCENE, out, McapOptions(without=("images",)))
    point_files = [r for r in tables.sample_data if r["channel"] in ("LIDAR_TOP", *RADARS)]
    assert result.sensor_bytes == sum((tables.root / r["filename"]).stat().st_size for r in point_files) > 0
    from_files = read_messages(out)
    for radar in RADARS:
        assert [m.data for m in from_files[f"/{radar}"]] == [m.data for m in messages[f"/{radar}"]]
    for a, b in zip(from_files["/LIDAR_TOP"], messages["/LIDAR_TOP"]):
        five = ["x", "y", "z", "intensity", "ring"]
        pa, pb = point_fields(a.message), point_fields(b.message)
        assert all(np.array_equal(pa[n], pb[n]) for n in five) and pa.dtype.names == tuple(five)


def test_can_bus_messages_are_the_files_records(exported, tables):
    _, _, messages = exported
    for message in ("ms_imu", "pose", "steeranglefeedback", "vehicle_monitor", "zoe_veh_info"):
        items = messages[f"/can_bus/{message}"]
        records = sorted(tables.can_bus(message), key=lambda r: r["utime"])
        assert [m.message for m in items] == records
        assert [m.log_time_ns for m in items] == [r["utime"] * 1000 for r in records]
        assert {m.schema_name for m in items} == {f"nuscenes.can_bus.{message}"}


def _map_geometry(root: Path, location: str):
    """{layer: shapely geometries} of the map expansion JSON, built by hand."""
    data = json.loads((root / "maps" / "expansion" / f"{location}.json").read_text())
    nodes = {n["token"]: (n["x"], n["y"]) for n in data["node"]}
    polygons = {p["token"]: shapely.Polygon([nodes[t] for t in p["exterior_node_tokens"]],
                                            [[nodes[t] for t in hole["node_tokens"]] for hole in p["holes"]])
                for p in data["polygon"]}
    lines = {ln["token"]: shapely.LineString([nodes[t] for t in ln["node_tokens"]]) for ln in data["line"]}
    out = {"drivable_area": [polygons[t] for r in data["drivable_area"] for t in r["polygon_tokens"]]}
    for layer in ("lane", "walkway", "ped_crossing", "stop_line", "carpark_area"):
        out[layer] = [polygons[r["polygon_token"]] for r in data[layer]]
    for layer in ("road_divider", "lane_divider"):
        out[layer] = [lines[r["line_token"]] for r in data[layer]]
    return out


def _route_box(tables: Tables, margin_m: float) -> tuple[float, float, float, float]:
    """The ego route's bounding box (every sample_data's ego pose, from the JSON) grown by `margin_m`, by hand."""
    ego = np.array([tables.ego_pose[r["ego_pose_token"]]["translation"][:2] for r in tables.sample_data])
    return (*(ego.min(axis=0) - margin_m), *(ego.max(axis=0) + margin_m))


def _assert_map_is_the_json_map_clipped_to(update, tables: Tables, box) -> np.ndarray:
    """Every layer of the /map SceneUpdate covers the area (polygons) or length (lines) of the map expansion JSON's
    geometries clipped to `box`; returns the (K, 2) points of every layer."""
    geometry = _map_geometry(tables.root, tables.log["location"])
    entities = {e.id: e for e in update.entities}
    assert {"map/drivable_area", "map/lane", "map/road_divider", "map/lane_divider"} <= set(entities)
    everywhere = []
    for layer, geoms in geometry.items():
        clipped = [shapely.clip_by_rect(g, *box) for g in geoms]
        if f"map/{layer}" not in entities:
            assert sum(g.area + g.length for g in clipped) == 0
            continue
        entity = entities[f"map/{layer}"]
        if entity.triangles:
            tri = entity.triangles[0]
            points = np.array([[p.x, p.y] for p in tri.points])[list(tri.indices)].reshape(-1, 3, 2)
            u, v = points[:, 1] - points[:, 0], points[:, 2] - points[:, 0]
            area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum()
            assert area == pytest.approx(sum(g.area for g in clipped), rel=1e-6)
        else:
            line = entity.lines[0]
            points = np.array([[p.x, p.y] for p in line.points])[list(line.indices)].reshape(-1, 2, 2)
            length = np.linalg.norm(points[:, 1] - points[:, 0], axis=1).sum()
            assert length == pytest.approx(sum(g.length for g in clipped), rel=1e-6)
        everywhere.append(points.reshape(-1, 2))
    return np.concatenate(everywhere)


def test_the_map_around_the_route_is_drawn_once(exported, tables):
    _, _, messages = exported
    (item,) = messages["/map"]
    assert item.log_time_ns == min(r["timestamp"] for r in tables.sample_data) * 1000
    box = _route_box(tables, 50)
    points = _assert_map_is_the_json_map_clipped_to(item.message, tables, box)
    assert points[:, 0].min() >= box[0] - 1e-6 and points[:, 0].max() <= box[2] + 1e-6


def test_the_map_reaches_the_margin_on_every_side_of_the_route_and_stops_there(synth_points_out, tables, tmp_path):
    """With --map-margin-m 10, map elements up to 10 m beyond the route's extremes (both sides of both axes) are
    drawn and clipped at 10 m: the JSON map reaches farther on every side, so the clipped geometry touches the box's
    four edges and no point lies outside it."""
    margin_m = 10.0
    box = _route_box(tables, margin_m)
    geometry = _map_geometry(tables.root, tables.log["location"])
    bounds = shapely.total_bounds(np.array([g for geoms in geometry.values() for g in geoms], dtype=object))
    assert bounds[0] < box[0] and bounds[1] < box[1] and bounds[2] > box[2] and bounds[3] > box[3]
    out = tmp_path / "map.mcap"
    result = export_mcap(synth_points_out, SCENE, out, McapOptions(map_margin_m=margin_m, without=(
        "images", "points", "boxes", "can_bus", "transforms")))
    # every other content left out (no /tf without transforms); the cameras' calibrations stay
    assert set(result.messages) == {"/map", *(f"/{c}/camera_info" for c in CAMERAS)}
    (item,) = read_messages(out)["/map"]
    points = _assert_map_is_the_json_map_clipped_to(item.message, tables, box)
    np.testing.assert_allclose([*points.min(axis=0), *points.max(axis=0)], box, rtol=0, atol=1e-6)


def test_progress_counts_every_message(exported):
    result, events, _ = exported
    assert events[-1].finished and events[-1].done == events[-1].total == result.total_messages
    assert [e.done for e in events] == sorted(e.done for e in events)


def test_the_size_is_in_the_order_of_the_sensor_files(exported, tables):
    result, _, _ = exported
    files = sum((tables.root / r["filename"]).stat().st_size for r in tables.sample_data)
    assert result.sensor_bytes == files
    # the synthetic JPEGs (flat colours) and clouds compress well; the real extract's do not (tests/parity)
    assert 0.2 * files < result.bytes < 1.3 * files


def test_the_same_options_give_the_same_bytes(exported, synth_points_out, tmp_path):
    result, _, _ = exported
    again = tmp_path / "again.mcap"
    export_mcap(synth_points_out, SCENE, again)
    assert again.read_bytes() == result.out.read_bytes()


def test_lz4_and_keyframe_boxes_and_contents_left_out(synth_points_out, tables, tmp_path):
    out = tmp_path / "small.mcap"
    result = export_mcap(synth_points_out, SCENE, out, McapOptions(boxes="keyframes", compression="lz4",
                                                       without=("images", "points", "can_bus", "map")))
    assert validate(out)["compression"] == {"lz4"}
    topics = set(result.messages)
    assert topics == {"/tf", "/markers/annotations", *(f"/{c}/camera_info" for c in CAMERAS)}
    messages = read_messages(out)
    assert [m.log_time_ns // 1000 for m in messages["/markers/annotations"]] == sorted(
        s["timestamp"] for s in tables.samples)
    # keyframe boxes are the annotations as they are: each box says it is not interpolated
    flags = [{kv.key: kv.value for kv in e.metadata}["interpolated"] for m in messages["/markers/annotations"]
             for e in m.message.entities]
    assert len(flags) == len(tables.annotations) and set(flags) == {"false"}


def test_a_missing_file_is_skipped_and_named_or_stops_the_export(synth_points_out, synth_root, tmp_path):
    import shutil

    dataroot = tmp_path / "data"
    shutil.copytree(synth_root, dataroot)
    frames = (pl.scan_parquet(f"{synth_points_out}/frames/**/*.parquet")
              .filter((pl.col("scene_name") == SCENE) & (pl.col("channel").cast(pl.String) == "CAM_BACK"))
              .sort("timestamp").select("filename").collect()["filename"].to_list())
    (dataroot / frames[1]).unlink()
    out = tmp_path / "scene.mcap"
    result = export_mcap(nuparquet.open(synth_points_out, dataroot=dataroot), SCENE, out, McapOptions(without=("points",)))
    assert result.missing == [str(dataroot / frames[1])]
    assert result.messages["/CAM_BACK/image_rect_compressed"] == len(frames) - 1
    assert result.messages["/CAM_BACK/camera_info"] == len(frames)
    before = out.read_bytes()
    with pytest.raises(InputError, match=frames[1].split("/")[-1]):
        export_mcap(nuparquet.open(synth_points_out, dataroot=dataroot), SCENE, out, McapOptions(on_missing="error"))
    assert out.read_bytes() == before  # the earlier file is intact, no partial is left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data", "scene.mcap"]


def test_cli_writes_the_file_and_names_bad_input(synth_points_out, tmp_path, capsys):
    out = tmp_path / "cli.mcap"
    assert main(["export-mcap", str(synth_points_out), "--scene", SCENE, "--out", str(out), "--quiet",
                 "--without", "images,points"]) == 0
    assert "message(s)" in capsys.readouterr().out and out.is_file()
    assert main(["export-mcap", str(synth_points_out), "--scene", "scene-9999", "--out", str(out)]) == 2
    assert "valid scenes: scene-0001, scene-0002" in capsys.readouterr().err
    assert main(["export-mcap", str(synth_points_out), "--scene", SCENE, "--out", str(out), "--without", "cats"]) == 2
    assert "unknown content cats" in capsys.readouterr().err
    assert main(["export-mcap", str(synth_points_out), "--scene", SCENE]) == 2
    assert main(["export-mcap", str(synth_points_out), "--scene", SCENE, "--out",
                 str(synth_points_out / "x.mcap")]) == 2
    assert "inside the converted dataset" in capsys.readouterr().err
    with pytest.raises(UsageError, match="--out-dir"):
        from nuparquet.mcap import export_scenes
        export_scenes(synth_points_out, nuparquet.SceneSelection(all_scenes=True), None, McapOptions())


def test_the_scene_query_refuses_an_unknown_scene_listing_every_valid_one(synth_points_out, synth_root):
    """load_scene's own check (export_mcap asks Dataset.check_scenes first; a direct caller has only this one): the
    names are the JSON scene table's, sorted, joined by ", "."""
    from nuparquet.mcap.scene import load_scene

    names = sorted(s["name"] for s in json.loads((synth_root / VERSION / "scene.json").read_text()))
    assert len(names) > 1
    with pytest.raises(UsageError) as raised:
        load_scene(nuparquet.open(synth_points_out), "scene-9999")
    assert str(raised.value) == f"unknown scene 'scene-9999'; valid scenes: {', '.join(names)}"


def test_foxglove_schemas_are_embedded_for_every_protobuf_topic(exported):
    _, _, messages = exported
    names = {topic: items[0].schema_name for topic, items in messages.items()}
    assert names["/tf"] == "foxglove.FrameTransforms"
    assert names["/LIDAR_TOP"] == names["/RADAR_FRONT"] == "foxglove.PointCloud"
    assert names["/markers/annotations"] == names["/map"] == "foxglove.SceneUpdate"
    assert names["/CAM_FRONT/camera_info"] == "foxglove.CameraCalibration"
    assert Counter(names.values())["foxglove.CompressedImage"] == len(CAMERAS)


def test_the_scene_metadata_and_the_can_bus_json_schemas_are_what_a_reader_is_told(synth_points_out, tables, tmp_path):
    """The file's "scene" metadata record holds the scene's and its log's JSON fields (a viewer shows them), and each
    CAN bus topic is JSON whose schema is declared as a JSON Schema (encoding "jsonschema", as MCAP's registry
    names it and Foxglove reads it) listing every field of its messages. Exported here, in this test's process."""
    from mcap.reader import SeekingReader

    out = tmp_path / "can.mcap"
    export_mcap(synth_points_out, SCENE, out, McapOptions(without=("images", "points", "boxes", "map",
                                                                      "transforms")))
    with open(out, "rb") as f:
        reader = SeekingReader(f)
        metadata = [(m.name, m.metadata) for m in reader.iter_metadata()]
        summary = reader.get_summary()
    assert tables.scene["description"]  # the generator writes one: the record must carry it
    assert metadata == [("scene", {"name": SCENE, "description": tables.scene["description"],
                                   "log_location": tables.log["location"], "vehicle": tables.log["vehicle"],
                                   "date_captured": tables.log["date_captured"], "source_version": VERSION})]
    channels = {c.topic: c for c in summary.channels.values() if c.topic.startswith("/can_bus/")}
    assert set(channels) == {f"/can_bus/{m}" for m in ("ms_imu", "pose", "steeranglefeedback", "vehicle_monitor",
                                                       "zoe_veh_info")}
    for topic, channel in channels.items():
        schema = summary.schemas[channel.schema_id]
        assert (channel.message_encoding, schema.encoding) == ("json", "jsonschema")
        declared = json.loads(schema.data)
        assert declared["type"] == "object"
        fields = {key for record in tables.can_bus(topic.split("/")[-1]) for key in record}
        assert set(declared["properties"]) == fields


def test_chunk_bytes_takes_1024_and_refuses_less(synth_points_out, tmp_path):
    """chunk_bytes (the MCAP writer's chunk size) has a floor of 1024 bytes: 1024 itself writes a valid file, of
    many chunks; 1023 is refused naming the option and the value."""
    with pytest.raises(UsageError, match="chunk_bytes must be at least 1024, got 1023"):
        McapOptions(chunk_bytes=1023)
    out = tmp_path / "small-chunks.mcap"
    export_mcap(synth_points_out, SCENE, out, McapOptions(chunk_bytes=1024, without=("images", "points",
                                                                                          "map", "boxes")))
    assert len(validate(out)["chunks"]) > 1


def test_an_unreadable_point_file_stops_the_export_with_the_reason(synth_out, synth_root, tmp_path):
    """With --on-missing error, a lidar file that is gone or truncated stops the export with an InputError naming
    the file and why (neither converted nor a file; the point reader's reason for a truncated file): read from the files, as a dataset
    converted without points is."""
    import os
    import shutil

    dataroot = tmp_path / "data"
    shutil.copytree(synth_root, dataroot, copy_function=os.symlink)  # links: only the two files below change
    frames = (pl.scan_parquet(f"{synth_out}/frames/**/*.parquet")
              .filter((pl.col("scene_name") == SCENE) & (pl.col("channel").cast(pl.String) == "LIDAR_TOP"))
              .sort("timestamp").select("filename").collect()["filename"].to_list())
    (dataroot / frames[0]).unlink()
    options = McapOptions(on_missing="error", without=("images", "boxes", "map", "can_bus"))
    ds = nuparquet.open(synth_out, dataroot=dataroot)
    with pytest.raises(InputError) as raised:  # the one reader's word: neither converted nor a file
        export_mcap(ds, SCENE, tmp_path / "a.mcap", options)
    assert str(raised.value).startswith(f"sensor file {dataroot / frames[0]}: not converted, and no such file")
    (dataroot / frames[0]).write_bytes(b"\0" * 22)  # 5.5 float32: not whole 5-float points
    with pytest.raises(InputError) as raised:
        export_mcap(ds, SCENE, tmp_path / "b.mcap", options)
    assert str(raised.value).startswith(f"sensor file {dataroot / frames[0]}: 22 bytes is not a whole number of "
                                        "5-float32 points")


def _documented_rank(topic: str) -> tuple:
    """The stream order `mcap.export` documents for messages of equal log time: the map, /tf, each sensor channel
    by name (a camera's camera_info before its image), the boxes, the CAN bus messages by name."""
    if topic == "/map":
        return (0,)
    if topic == "/tf":
        return (1,)
    if topic == "/markers/annotations":
        return (3,)
    if topic.startswith("/can_bus/"):
        return (4, topic)
    channel, _, kind = topic[1:].partition("/")
    return (2, channel, {"": 0, "camera_info": 0, "image_rect_compressed": 1}[kind])


def test_messages_of_equal_log_time_keep_the_documented_stream_order(exported):
    """A frame's /tf comes before its camera_info and its image, a camera's calibration before its image, and every
    group of messages sharing a log time is in the documented stream order (a sort by time alone would leave the
    ties to the merge's whims)."""
    from mcap.reader import NonSeekingReader

    result, _, _ = exported
    with open(result.out, "rb") as f:
        records = [(message.log_time, channel.topic) for _, channel, message
                   in NonSeekingReader(f, validate_crcs=True).iter_messages()]
    by_time = defaultdict(list)
    for time_ns, topic in records:
        by_time[time_ns].append(topic)
    ties = {t: topics for t, topics in by_time.items() if len(set(topics)) > 1}
    assert len(ties) > 10  # the scene has frames whose /tf, calibration and image share a time
    for time_ns, topics in ties.items():
        ranks = [_documented_rank(topic) for topic in topics]
        assert ranks == sorted(ranks), (time_ns, topics)
    camera_ties = [topics for topics in ties.values() if any(t.endswith("/image_rect_compressed") for t in topics)]
    assert camera_ties and all(topics.index("/tf") < min(i for i, t in enumerate(topics) if t.endswith("/camera_info"))
                               for topics in camera_ties if "/tf" in topics)
