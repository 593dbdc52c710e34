"""The synthetic generator writes what a nuScenes user expects: the exact layout and schema, consistent
linkage, devkit compatibility, painted images that line up with the devkit's boxes, lidar/radar files the
devkit reads, and byte-identical output for the same seed."""

from __future__ import annotations

import json
import re
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from pyquaternion import Quaternion

from nuparquet.errors import UsageError
from nuparquet.synth import synthesize
from conftest import EXTRACT_ROOT, EXTRACT_VERSION, NUSCENES_CHANNELS, REPO, SYNTH_VERSION

TABLES = ("attribute", "calibrated_sensor", "category", "ego_pose", "instance", "log", "map", "sample",
          "sample_annotation", "sample_data", "scene", "sensor", "visibility")


def load_tables(root: Path, version: str = SYNTH_VERSION) -> dict[str, list[dict]]:
    return {name: json.loads((root / version / f"{name}.json").read_text()) for name in TABLES}


def by_token(records: list[dict]) -> dict[str, dict]:
    return {r["token"]: r for r in records}


@pytest.fixture(scope="session")
def tables(synth_root) -> dict[str, list[dict]]:
    return load_tables(synth_root)


# -- determinism ----------------------------------------------------------------------------------------------

def table_bytes(root: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((root / SYNTH_VERSION).glob("*.json"))}


def test_same_seed_gives_byte_identical_tables_and_another_seed_does_not(tmp_path):
    for name, seed in (("a", 5), ("b", 5), ("c", 6)):
        synthesize(tmp_path / name, scenes=3, samples_per_scene=5, seed=seed, version=SYNTH_VERSION)
    a, b, c = (table_bytes(tmp_path / name) for name in "abc")
    assert sorted(a) == sorted(f"{t}.json" for t in TABLES)
    assert a == b
    assert a["sample_annotation.json"] != c["sample_annotation.json"]
    assert a["ego_pose.json"] != c["ego_pose.json"]


def test_sensor_files_are_deterministic_too(synth_root, tmp_path):
    again = tmp_path / "again"
    synthesize(again, scenes=2, samples_per_scene=6, with_images=True, with_lidar=True, seed=7, version=SYNTH_VERSION)
    for pattern in ("samples/CAM_FRONT/*.jpg", "sweeps/LIDAR_TOP/*.pcd.bin", "samples/RADAR_FRONT/*.pcd"):
        first = sorted(synth_root.glob(pattern))
        assert first and [p.name for p in first] == [p.name for p in sorted(again.glob(pattern))]
        assert all(p.read_bytes() == (again / p.relative_to(synth_root)).read_bytes() for p in first[:5])


# -- layout and schema ----------------------------------------------------------------------------------------

def test_files_have_the_json_layout_and_key_order_of_the_real_tables(synth_root, tables):
    for name in TABLES:
        text = (synth_root / SYNTH_VERSION / f"{name}.json").read_text()
        assert text == json.dumps(tables[name], indent=0), name  # the real tables' layout
        schema = json.loads((REPO / "schemas" / "tables" / f"{name}.json").read_text())
        expected = [f["name"] for f in schema["fields"]]
        assert tables[name], name
        assert all(list(record) == expected for record in tables[name]), name
        real = EXTRACT_ROOT / EXTRACT_VERSION / f"{name}.json"
        if real.is_file():  # and the real extract agrees, field for field, in order
            assert list(json.loads(real.read_text())[0]) == expected, name


def test_vocabulary_is_nuscenes(tables, devkit):
    from nuscenes.utils.color_map import get_colormap

    assert {s["channel"] for s in tables["sensor"]} == NUSCENES_CHANNELS
    assert {c["name"] for c in tables["category"]} <= set(get_colormap())
    assert [v["token"] for v in tables["visibility"]] == ["1", "2", "3", "4"]
    assert list(tables["map"][0]) == ["category", "token", "filename", "log_tokens"]
    assert list(tables["visibility"][0]) == ["description", "token", "level"]
    assert {a["name"] for a in tables["attribute"]} == {
        "vehicle.moving", "vehicle.stopped", "vehicle.parked", "cycle.with_rider", "cycle.without_rider",
        "pedestrian.sitting_lying_down", "pedestrian.standing", "pedestrian.moving"}
    assert len({log["location"] for log in tables["log"]}) >= 2
    assert all(re.fullmatch(r"scene-\d{4}", s["name"]) for s in tables["scene"])
    tokens = [r["token"] for name in ("sample", "sample_data", "sample_annotation", "instance", "scene", "log")
              for r in tables[name]]
    assert all(re.fullmatch(r"[0-9a-f]{32}", t) for t in tokens)


def test_filenames_and_image_sizes_follow_nuscenes(tables):
    channel_of = {c["token"]: s["channel"] for c in tables["calibrated_sensor"] for s in tables["sensor"]
                  if s["token"] == c["sensor_token"]}
    logfiles = {log["logfile"] for log in tables["log"]}
    for sd in tables["sample_data"]:
        channel = channel_of[sd["calibrated_sensor_token"]]
        folder, name = re.fullmatch(r"(samples|sweeps)/[A-Z_]+/(.+)", sd["filename"]).groups()
        assert folder == ("samples" if sd["is_key_frame"] else "sweeps")
        logfile, file_channel, stamp = re.fullmatch(r"(.+)__([A-Z_]+)__(\d+)\.(?:jpg|pcd\.bin|pcd)", name).groups()
        assert logfile in logfiles and file_channel == channel and int(stamp) == sd["timestamp"]
        ext = {"CAM": ".jpg", "LIDAR": ".pcd.bin", "RADAR": ".pcd"}[channel.split("_")[0]]
        assert sd["filename"].endswith(ext) and sd["filename"][: -len(ext)].count(".") == 0
        if channel.startswith("CAM"):
            assert (sd["fileformat"], sd["width"], sd["height"]) == ("jpg", 1600, 900)
        else:
            assert (sd["fileformat"], sd["width"], sd["height"]) == ("pcd", 0, 0)


def test_camera_calibrations_look_forward_along_z_with_1600x900_intrinsics(tables):
    from pyquaternion import Quaternion

    sensors = by_token(tables["sensor"])
    for cs in tables["calibrated_sensor"]:
        if sensors[cs["sensor_token"]]["modality"] != "camera":
            assert cs["camera_intrinsic"] == []
            continue
        ego_from_camera = Quaternion(cs["rotation"]).rotation_matrix
        assert abs(ego_from_camera[2, 2]) < 0.05  # optical axis (z) horizontal
        assert ego_from_camera[2, 1] < -0.99  # image y points down
        k = np.array(cs["camera_intrinsic"])
        assert k.shape == (3, 3) and 700 < k[0, 0] < 1400 and 700 < k[0, 2] < 900 and 400 < k[1, 2] < 520


# -- linkage --------------------------------------------------------------------------------------------------

def test_prev_next_links_resolve_within_their_table_and_are_mutual(tables):
    for name in ("sample", "sample_data", "sample_annotation"):
        records = by_token(tables[name])
        for r in records.values():
            if r["prev"]:
                assert records[r["prev"]]["next"] == r["token"], name
            if r["next"]:
                assert records[r["next"]]["prev"] == r["token"], name


def test_a_readings_next_is_the_following_reading_of_its_channel_and_scene(tmp_path):
    """sample_data's prev and next link each reading to the one just before and after it in time among the readings
    of its channel in its scene ('' at both ends), the chain the devkit walks. Generated in the test (tables only,
    ~0.1 s) rather than read from a session fixture: mutation runs map a generator function to the tests it runs in."""
    root = synthesize(tmp_path / "data", scenes=2, samples_per_scene=3, seed=9, version=SYNTH_VERSION)
    t = load_tables(root)
    scene_of = {s["token"]: s["scene_token"] for s in t["sample"]}
    channel_of = {c["token"]: c["sensor_token"] for c in t["calibrated_sensor"]}
    readings = defaultdict(list)
    for sd in t["sample_data"]:
        readings[(scene_of[sd["sample_token"]], channel_of[sd["calibrated_sensor_token"]])].append(sd)
    assert len(readings) == 2 * len(NUSCENES_CHANNELS)
    for chain in readings.values():
        chain.sort(key=lambda sd: sd["timestamp"])
        tokens = ["", *(sd["token"] for sd in chain), ""]
        assert [sd["prev"] for sd in chain] == tokens[:-2] and [sd["next"] for sd in chain] == tokens[2:]


def test_scene_and_sample_chains_are_consistent(tables):
    samples = by_token(tables["sample"])
    for scene in tables["scene"]:
        chain = [samples[scene["first_sample_token"]]]
        while chain[-1]["next"]:
            chain.append(samples[chain[-1]["next"]])
        assert chain[0]["prev"] == "" and chain[-1]["token"] == scene["last_sample_token"]
        assert len(chain) == scene["nbr_samples"]
        assert all(s["scene_token"] == scene["token"] for s in chain)
        gaps = np.diff([s["timestamp"] for s in chain])
        assert np.all((gaps > 450_000) & (gaps < 550_000))  # 2 Hz keyframes
    assert sum(s["nbr_samples"] for s in tables["scene"]) == len(tables["sample"])


def test_channel_chains_have_one_keyframe_per_sample_and_sweeps_belong_to_the_next_keyframe(tables):
    samples = by_token(tables["sample"])
    sample_data = by_token(tables["sample_data"])
    ego_poses = by_token(tables["ego_pose"])
    channel_of = {c["token"]: s["channel"] for c in tables["calibrated_sensor"] for s in tables["sensor"]
                  if s["token"] == c["sensor_token"]}
    keyframes = defaultdict(list)
    chains = 0
    for head in (sd for sd in tables["sample_data"] if sd["prev"] == ""):
        chain = [head]
        while chain[-1]["next"]:
            chain.append(sample_data[chain[-1]["next"]])
        chains += 1
        channel = channel_of[head["calibrated_sensor_token"]]
        assert all(channel_of[sd["calibrated_sensor_token"]] == channel for sd in chain)
        assert chain[0]["is_key_frame"] and chain[-1]["is_key_frame"]  # like the real scenes
        stamps = [sd["timestamp"] for sd in chain]
        assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
        next_keyframe_sample = None
        for sd in reversed(chain):  # walking backwards, the latest keyframe seen is the next one in time
            if sd["is_key_frame"]:
                next_keyframe_sample = sd["sample_token"]
                keyframes[(sd["sample_token"], channel)].append(sd)
                assert abs(sd["timestamp"] - samples[sd["sample_token"]]["timestamp"]) < 50_000
            else:
                assert sd["sample_token"] == next_keyframe_sample
                sample = samples[sd["sample_token"]]
                assert samples[sample["prev"]]["timestamp"] < sd["timestamp"] < sample["timestamp"]
        period_ms = np.median(np.diff(stamps)) / 1000
        expected = {"CAM": (70, 95), "LIDAR": (45, 55), "RADAR": (65, 85)}[channel.split("_")[0]]
        assert expected[0] <= period_ms <= expected[1], (channel, period_ms)  # ~12 Hz, 20 Hz, ~13 Hz
    assert chains == len(tables["scene"]) * len(NUSCENES_CHANNELS)
    assert len(keyframes) == len(tables["sample"]) * len(NUSCENES_CHANNELS)
    assert all(len(v) == 1 for v in keyframes.values())
    lidar_keyframes = [v[0] for (_, channel), v in keyframes.items() if channel == "LIDAR_TOP"]
    assert all(sd["timestamp"] == samples[sd["sample_token"]]["timestamp"] for sd in lidar_keyframes)
    for sd in tables["sample_data"]:
        assert sd["ego_pose_token"] == sd["token"]
        assert ego_poses[sd["token"]]["timestamp"] == sd["timestamp"]
    assert len(ego_poses) == len(sample_data)


def test_instance_tracks_cover_consecutive_samples(tables):
    samples = by_token(tables["sample"])
    annotations = by_token(tables["sample_annotation"])
    scene_of = {s["token"]: s["scene_token"] for s in tables["sample"]}
    first_sample = {s["token"]: s["first_sample_token"] for s in tables["scene"]}
    last_sample = {s["token"]: s["last_sample_token"] for s in tables["scene"]}
    counts, late, early = [], 0, 0
    for instance in tables["instance"]:
        track = [annotations[instance["first_annotation_token"]]]
        assert track[0]["prev"] == ""
        while track[-1]["next"]:
            nxt = annotations[track[-1]["next"]]
            assert samples[nxt["sample_token"]]["prev"] == track[-1]["sample_token"]
            track.append(nxt)
        assert track[-1]["token"] == instance["last_annotation_token"]
        assert len(track) == instance["nbr_annotations"]
        assert all(a["instance_token"] == instance["token"] for a in track)
        counts.append(len(track))
        scene = scene_of[track[0]["sample_token"]]
        late += track[0]["sample_token"] != first_sample[scene]
        early += track[-1]["sample_token"] != last_sample[scene]
    assert sum(counts) == len(annotations)
    assert min(counts) == 1  # single-annotation tracks exist
    assert max(counts) == max(s["nbr_samples"] for s in tables["scene"])  # and tracks over a whole scene
    assert late > 0 and early > 0


def test_annotations_are_plausible(tables):
    categories = by_token(tables["category"])
    attributes = by_token(tables["attribute"])
    instances = by_token(tables["instance"])
    annotations = tables["sample_annotation"]
    assert len(annotations) / len(tables["sample"]) > 15
    moving = 0
    for a in annotations:
        category = categories[instances[a["instance_token"]]["category_token"]]["name"]
        names = [attributes[t]["name"] for t in a["attribute_tokens"]]
        if category.startswith("human.pedestrian"):
            assert len(names) == 1 and names[0].startswith("pedestrian.")
        elif category in ("vehicle.bicycle", "vehicle.motorcycle"):
            assert len(names) == 1 and names[0].startswith("cycle.")
        elif category.startswith("vehicle."):
            assert len(names) == 1 and names[0].startswith("vehicle.")
        else:
            assert names == []
        moving += names == ["vehicle.moving"]
        assert a["visibility_token"] in {"1", "2", "3", "4"}
        assert all(s > 0 for s in a["size"]) and np.isfinite(a["translation"]).all()
        assert a["num_lidar_pts"] >= 0 and a["num_radar_pts"] >= 0
    assert moving > 0
    assert any(a["num_lidar_pts"] == 0 for a in annotations) and any(a["num_lidar_pts"] > 100 for a in annotations)


def test_quaternions_are_unit_norm(tables):
    for name in ("ego_pose", "calibrated_sensor", "sample_annotation"):
        q = np.array([r["rotation"] for r in tables[name]])
        assert np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) < 1e-9), name


def test_ego_moves_smoothly_at_plausible_speeds(tables):
    samples = by_token(tables["sample"])
    poses = by_token(tables["ego_pose"])
    lidar = {sd["sample_token"]: poses[sd["token"]] for sd in tables["sample_data"]
             if sd["is_key_frame"] and sd["filename"].startswith("samples/LIDAR_TOP/")}
    for scene in tables["scene"]:
        tokens = [scene["first_sample_token"]]
        while samples[tokens[-1]]["next"]:
            tokens.append(samples[tokens[-1]]["next"])
        xy = np.array([lidar[t]["translation"][:2] for t in tokens])
        t_s = np.array([lidar[t]["timestamp"] for t in tokens]) / 1e6
        speed = np.linalg.norm(np.diff(xy, axis=0), axis=1) / np.diff(t_s)
        assert np.all(speed <= 15.5)


def test_lidar_points_lie_on_faces_that_face_the_sensor_none_in_a_box_around_it():
    """The sensors module's promise: num_lidar_pts points on the sensor-facing faces of each box. A bus standing over
    the lidar (the sensor inside it: no face faces the sensor) gets none of its 150, and no ground return falls under
    it; a car 12 m ahead gets its 150, on its faces that face the sensor (rear and top). Checked in the box frames
    with pyquaternion, from the lidar keyframe's ego pose and calibration."""
    import dataclasses

    from nuparquet.synth.plan import make_rig
    from nuparquet.synth.sensors import SceneSensors
    from nuparquet.synth.timeline import make_timeline
    from nuparquet.synth.world import build_scene

    rng = np.random.default_rng(79)
    rig = make_rig(rng)
    timeline = make_timeline(rng, 1_532_402_927_647_951, 2, rig.channels)
    scene = build_scene(rng, timeline, True)
    lidar = [c.name for c in rig.channels].index("LIDAR_TOP")
    frame = int(np.flatnonzero((timeline.frame_channel == lidar) & timeline.frame_is_key_frame
                               & (timeline.frame_sample_index == 0))[0])
    ego = Quaternion(scene.ego_rotation[frame])
    sensor_m = scene.ego_translation_m[frame] + ego.rotate(rig.ego_from_sensor_translation_m[lidar])
    ahead_m = scene.ego_translation_m[frame] + ego.rotate([12.0, 0.0, 0.0])
    centers = np.array([[sensor_m[0], sensor_m[1], 2.0], [ahead_m[0], ahead_m[1], 0.8]])
    sizes = np.array([[3.0, 12.0, 4.0], [1.9, 4.6, 1.6]])  # a bus 4 m high over the 1.8 m high lidar; a car
    rotations = np.array([scene.ego_rotation[frame]] * 2)
    scene = dataclasses.replace(
        scene, instance_category=scene.instance_category[:2], instance_first_annotation=np.arange(2),
        instance_n_annotations=np.ones(2, dtype=np.int64), annotation_instance=np.arange(2),
        annotation_sample=np.zeros(2, dtype=np.int64), annotation_translation_m=centers, annotation_size_m=sizes,
        annotation_rotation=rotations, annotation_attribute=np.full(2, -1), annotation_visibility=np.full(2, 4),
        annotation_num_lidar_pts=np.full(2, 150), annotation_num_radar_pts=np.zeros(2, dtype=np.int64))
    points = SceneSensors(scene, rig, 79, 0).lidar_points(frame)[:, :3]
    calibration = Quaternion(rig.ego_from_sensor_rotation[lidar])
    global_m = np.array([ego.rotate(calibration.rotate(p)) for p in points]) + sensor_m
    local = [np.array([Quaternion(r).inverse.rotate(p - c) for p in global_m]) for c, r in zip(centers, rotations)]
    half = [np.array([size[1], size[0], size[2]]) / 2 for size in sizes]  # x along the length, y the width
    inside = [np.all(np.abs(lo) <= h + 1e-6, axis=1) for lo, h in zip(local, half)]
    assert not inside[0].any()
    assert inside[1].sum() == 150
    car = local[1][inside[1]] / half[1]
    on_rear, on_top = np.isclose(car[:, 0], -0.97, atol=1e-4), np.isclose(car[:, 2], 0.97, atol=1e-4)
    assert np.all(on_rear | on_top) and on_rear.any() and on_top.any()


# -- API and CLI ----------------------------------------------------------------------------------------------

def test_bad_arguments_raise_usage_errors(tmp_path):
    with pytest.raises(UsageError):
        synthesize(tmp_path, scenes=0)
    with pytest.raises(UsageError):
        synthesize(tmp_path, scenes=1, samples_per_scene=0)
    with pytest.raises(UsageError):
        synthesize(tmp_path, scenes=1, seed=-1)


def test_cli_writes_a_dataset_and_exits_0(tmp_path, capsys):
    from nuparquet.cli.main import main

    out = tmp_path / "cli"
    assert main(["synth", str(out), "--scenes", "2", "--samples-per-scene", "3", "--seed", "4", "--quiet"]) == 0
    assert len(json.loads((out / "v1.0-synth" / "sample.json").read_text())) == 6
    assert "wrote" in capsys.readouterr().err


def test_cli_exits_2_for_zero_scenes(tmp_path, capsys):
    from nuparquet.cli.main import main

    assert main(["synth", str(tmp_path / "x"), "--scenes", "0"]) == 2
    assert "--scenes" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_palette_is_the_devkit_colormap():
    from nuscenes.utils.color_map import get_colormap

    from nuparquet.rendering.palette import CATEGORY_RGB, category_rgb

    assert CATEGORY_RGB == get_colormap()
    assert category_rgb("vehicle.car") == (255, 158, 0)
    unknown = category_rgb("lyft.other_vehicle")
    assert unknown == category_rgb("lyft.other_vehicle") and all(40 <= c <= 215 for c in unknown)


@pytest.mark.parametrize("samples", [1, 2])
def test_scenes_too_short_for_every_can_bus_stream_get_no_can_bus_and_convert(tmp_path, samples):
    """vehicle_monitor's 2 Hz needs 0.5 s between the first message (2-15 ms after the first sample) and the last
    (0-20 ms before the last sample) for two messages: scenes of one or two keyframes (0 or 0.5 s) get no CAN bus
    files (they ended the generator in a numpy error), and convert with the CAN bus skipped."""
    from nuparquet.conversion import convert

    root = tmp_path / "data"
    synthesize(root, scenes=1, samples_per_scene=samples, seed=4, version=SYNTH_VERSION)
    assert not (root / "can_bus").exists()
    assert len(load_tables(root)["sample"]) == samples
    manifest = convert(root, SYNTH_VERSION, tmp_path / "out")
    assert manifest["skipped"]["can_bus"] == "no can_bus/ folder in the dataroot"


def test_the_shortest_scene_with_can_bus_has_two_vehicle_monitor_messages(tmp_path):
    """Three keyframes span 1 s: between 0.965 and 0.998 s of messages, two of vehicle_monitor's (every 0.5 s) and
    50 or so of pose's, each stream strictly inside the keyframes."""
    root = tmp_path / "data"
    synthesize(root, scenes=1, samples_per_scene=3, seed=4, version=SYNTH_VERSION)
    samples = sorted(r["timestamp"] for r in load_tables(root)["sample"])
    monitor = json.loads((root / "can_bus" / "scene-0001_vehicle_monitor.json").read_text())
    pose = json.loads((root / "can_bus" / "scene-0001_pose.json").read_text())
    assert len(monitor) == 2 and 48 <= len(pose) <= 50
    for messages in (monitor, pose):
        assert samples[0] < messages[0]["utime"] and messages[-1]["utime"] <= samples[-1]
