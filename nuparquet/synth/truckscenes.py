"""A deterministic MAN TruckScenes-format dataroot (`nuparquet synth --format truckscenes`): the fourteen tables
`truckscenes.TruckScenes` loads, camera JPEGs, and lidar and radar `.pcd` files as its devkit reads them (pypcd4).

    out/<version>/{attribute,calibrated_sensor,category,ego_motion_cabin,ego_motion_chassis,ego_pose,instance,
                   sample,sample_annotation,sample_data,scene,sensor,visibility,weather_annotation}.json
    out/samples/<CHANNEL>/<CHANNEL>_<timestamp>.{jpg,pcd}      keyframes
    out/sweeps/<CHANNEL>/<CHANNEL>_<timestamp>.{jpg,pcd}       one sweep between consecutive keyframes

What TruckScenes does differently from nuScenes is all here: no log and no map table (`scene.log_token` is ""),
a scene names its `weather_annotation`, `ego_motion_cabin` / `ego_motion_chassis` at 20 Hz, the TruckScenes
taxonomy (category `index`), 4 cameras, 6 lidars and 6 radars, lidar `.pcd` with per-point timestamps and radar
`.pcd` with relative velocities and RCS. Keyframes of each sensor are a few milliseconds off their sample's time,
so the ego pose nearest the sample (which the devkit's `get_sample_data` moves boxes with) is not the frame's own.
Tracks include one of a single annotation, one with a gap too long for a velocity, and an annotation without a
visibility (""). Same arguments, same bytes.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from nuparquet.atomic import atomic_directory
from nuparquet.synth.rigid import quat_from_yaw, quat_multiply
from nuparquet.synth.tokens import name_token, random_tokens

WIDTH, HEIGHT = 480, 300
INTERVAL_US = 500_000  # keyframes at 2 Hz
MOTION_INTERVAL_US = 50_000  # ego_motion_* at 20 Hz
START_US = 1_695_000_000_000_000
SPEED_M_S = 12.0
# (channel, modality, mount [x, y, z] m, yaw deg, keyframe offset from the sample's time, us)
SENSORS = (
    ("CAMERA_LEFT_FRONT", "camera", (2.2, 1.2, 2.8), 35.0, 11_000),
    ("CAMERA_RIGHT_FRONT", "camera", (2.2, -1.2, 2.8), -35.0, 13_000),
    ("CAMERA_LEFT_BACK", "camera", (1.8, 1.3, 2.8), 140.0, 15_000),
    ("CAMERA_RIGHT_BACK", "camera", (1.8, -1.3, 2.8), -140.0, 17_000),
    ("LIDAR_LEFT", "lidar", (2.0, 1.3, 2.0), 90.0, 1_000),
    ("LIDAR_RIGHT", "lidar", (2.0, -1.3, 2.0), -90.0, 2_000),
    ("LIDAR_TOP_FRONT", "lidar", (2.4, 0.0, 3.6), 0.0, 3_000),
    ("LIDAR_TOP_LEFT", "lidar", (1.0, 1.1, 3.6), 60.0, 4_000),
    ("LIDAR_TOP_RIGHT", "lidar", (1.0, -1.1, 3.6), -60.0, 5_000),
    ("LIDAR_REAR", "lidar", (-1.0, 0.0, 1.5), 180.0, 6_000),
    ("RADAR_LEFT_FRONT", "radar", (2.5, 1.1, 0.8), 30.0, 21_000),
    ("RADAR_LEFT_SIDE", "radar", (0.5, 1.3, 0.8), 90.0, 22_000),
    ("RADAR_LEFT_BACK", "radar", (-1.0, 1.2, 0.8), 150.0, 23_000),
    ("RADAR_RIGHT_FRONT", "radar", (2.5, -1.1, 0.8), -30.0, 24_000),
    ("RADAR_RIGHT_SIDE", "radar", (0.5, -1.3, 0.8), -90.0, 25_000),
    ("RADAR_RIGHT_BACK", "radar", (-1.0, -1.2, 0.8), -150.0, 26_000),
)
# The TruckScenes taxonomy (category `index` as in its category.json) and its attributes.
CATEGORIES = (
    "animal", "human.pedestrian.adult", "human.pedestrian.child", "human.pedestrian.construction_worker",
    "human.pedestrian.personal_mobility", "human.pedestrian.police_officer", "human.pedestrian.stroller",
    "human.pedestrian.wheelchair", "movable_object.barrier", "movable_object.debris",
    "movable_object.pushable_pullable", "movable_object.trafficcone", "static_object.bicycle_rack",
    "static_object.traffic_sign", "vehicle.bicycle", "vehicle.bus.bendy", "vehicle.bus.rigid", "vehicle.car",
    "vehicle.construction", "vehicle.emergency.ambulance", "vehicle.emergency.police", "vehicle.motorcycle",
    "vehicle.trailer", "vehicle.truck", "vehicle.train", "vehicle.other", "vehicle.ego_trailer",
)
ATTRIBUTES = ("pedestrian.moving", "pedestrian.sitting_lying_down", "pedestrian.standing", "cycle.with_rider",
              "cycle.without_rider", "vehicle.moving", "vehicle.parked", "vehicle.stopped",
              "traffic_sign.pole_mounted", "traffic_sign.overhanging", "traffic_sign.temporary")
VISIBILITIES = (("v0-40", "visibility of whole object is between 0 and 40%"),
                ("v40-60", "visibility of whole object is between 40 and 60%"),
                ("v60-80", "visibility of whole object is between 60 and 80%"),
                ("v80-100", "visibility of whole object is between 80 and 100%"))
# Scene tags (the scene's `description`, ";"-joined): scene i takes choice i of each group (modulo its size),
# so scenes differ in weather, area and lighting; weather.snow is one whose per-tag metrics the devkit reports NaN.
TAG_CHOICES = (("weather.clear", "weather.snow", "weather.rain"), ("area.highway", "area.city"), ("daytime.morning",),
               ("season.autumn",), ("lighting.illuminated", "lighting.dark"), ("structure.regular",),
               ("construction.unchanged",))
# (category, attributes, offset from the ego at the scene start [x, y] m, own speed m/s, size [w, l, h] m)
OBJECTS = (
    ("vehicle.car", ("vehicle.moving",), (18.0, 6.0), 14.0, (1.9, 4.6, 1.6)),
    ("vehicle.truck", ("vehicle.moving",), (24.0, -7.0), 11.0, (2.6, 9.5, 3.6)),
    ("human.pedestrian.adult", ("pedestrian.standing",), (-14.0, 9.0), 0.0, (0.7, 0.7, 1.8)),
    ("static_object.traffic_sign", ("traffic_sign.pole_mounted",), (30.0, -9.0), 0.0, (0.8, 0.2, 2.5)),
    ("vehicle.ego_trailer", (), (-9.0, 0.0), SPEED_M_S, (2.5, 13.6, 4.0)),
    ("animal", (), (11.0, -3.5), 0.0, (0.5, 1.1, 0.8)),
    ("vehicle.other", ("vehicle.parked",), (40.0, 8.0), 0.0, (2.4, 7.5, 3.0)),
)


def scene_name(scene_index: int) -> str:
    """The TruckScenes mini split's scene names first (mini_val's, then mini_train's: truckscenes-devkit's
    `create_splits_scenes`, so that its evaluation and ours find a split that holds the scenes), then names of
    the same pattern made up from the index."""
    from nuparquet.splits import scene_splits

    lists = scene_splits("truckscenes")
    known = [*lists["mini_val"], *lists["mini_train"]]
    if scene_index < len(known):
        return known[scene_index]
    return f"scene-{name_token('ts-scene', str(scene_index))}-{scene_index}"


def synthesize_truckscenes(dataroot: Path, scenes: int, samples_per_scene: int, seed: int, version: str) -> Path:
    """Write the dataroot (tables atomically into `dataroot/version`, replacing it) and return `dataroot`."""
    rng = np.random.default_rng([seed, 41])
    tables = _vocabulary()
    for name in ("calibrated_sensor", "ego_motion_cabin", "ego_motion_chassis", "ego_pose", "instance", "sample",
                 "sample_annotation", "sample_data", "scene", "weather_annotation"):
        tables[name] = []
    files: dict[str, bytes] = {}
    calibrations = [_calibration(rng, sensor) for sensor in SENSORS]
    tables["calibrated_sensor"] = calibrations
    for scene_index in range(scenes):
        start_us = START_US + scene_index * 3_600_000_000
        _scene(rng, tables, files, calibrations, scene_index, start_us, samples_per_scene)
    with atomic_directory(dataroot / version, overwrite=True) as partial:
        for name, records in tables.items():
            with (partial / f"{name}.json").open("w") as out:
                json.dump(records, out, indent=2)
    for filename, data in files.items():
        path = dataroot / filename
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return dataroot


def _vocabulary() -> dict[str, list[dict]]:
    return {
        "attribute": [{"token": name_token("ts-attribute", a), "name": a, "description": f"{a} (synthetic)"}
                      for a in ATTRIBUTES],
        "category": [{"token": name_token("ts-category", c), "name": c, "description": f"{c} (synthetic)",
                      "index": i} for i, c in enumerate(CATEGORIES)],
        "sensor": [{"token": name_token("ts-sensor", s[0]), "channel": s[0], "modality": s[1]} for s in SENSORS],
        "visibility": [{"description": d, "token": str(i + 1), "level": level}
                       for i, (level, d) in enumerate(VISIBILITIES)],
    }


def _calibration(rng: np.random.Generator, sensor: tuple) -> dict:
    channel, modality, mount, yaw_deg, _offset = sensor
    yaw = np.deg2rad(yaw_deg + rng.uniform(-0.5, 0.5))
    heading = quat_from_yaw(np.array([yaw]))[0]
    # cameras look along their z axis (x right, y down): the ego's x forward, turned by the yaw
    rotation = quat_multiply(heading, np.array([0.5, -0.5, 0.5, -0.5])) if modality == "camera" else heading
    record = {"token": random_tokens(rng, 1)[0], "sensor_token": name_token("ts-sensor", channel),
              "translation": [round(v + rng.uniform(-0.01, 0.01), 6) for v in mount],
              "rotation": [float(v) for v in rotation], "camera_intrinsic": []}
    if modality == "camera":
        focal = float(np.round(rng.uniform(380, 420), 4))
        record["camera_intrinsic"] = [[focal, 0.0, WIDTH / 2], [0.0, focal, HEIGHT / 2], [0.0, 0.0, 1.0]]
    return record


def _ego(t_us: np.ndarray | int, start_us: int) -> tuple[np.ndarray, np.ndarray]:
    """The truck's path: (translation [x, y, 0], yaw) at `t_us`, a gentle curve (TruckScenes' z is always 0)."""
    s = (np.asarray(t_us, dtype=np.float64) - start_us) / 1e6
    return np.stack([500.0 + SPEED_M_S * s, 200.0 + 0.2 * s ** 2, np.zeros_like(s)], axis=-1), 0.033 * s


def _scene(rng, tables, files, calibrations, scene_index, start_us, samples_per_scene) -> None:
    scene_token, weather_token = random_tokens(rng, 2)
    sample_tokens = random_tokens(rng, samples_per_scene)
    times = [start_us + k * INTERVAL_US for k in range(samples_per_scene)]
    for k, token in enumerate(sample_tokens):
        tables["sample"].append({"token": token, "timestamp": times[k], "prev": sample_tokens[k - 1] if k else "",
                                 "next": sample_tokens[k + 1] if k + 1 < samples_per_scene else "",
                                 "scene_token": scene_token})
    tables["weather_annotation"].append({"token": weather_token, "temperature": round(rng.uniform(275, 295), 2),
                                         "wind": round(rng.uniform(0, 8), 2), "precipitation": 0.0,
                                         "cloud_cover": int(rng.integers(0, 9)), "visibility": 10000.0})
    tables["scene"].append({"token": scene_token, "name": scene_name(scene_index),
                            "description": ";".join(c[scene_index % len(c)] for c in TAG_CHOICES), "log_token": "", "nbr_samples": samples_per_scene,
                            "first_sample_token": sample_tokens[0], "last_sample_token": sample_tokens[-1],
                            "weather_annotation_token": weather_token})
    for motion in ("ego_motion_cabin", "ego_motion_chassis"):
        for t in range(times[0] - 93_000, times[-1] + 100_001, MOTION_INTERVAL_US):  # off the samples' clock
            tables[motion].append(_motion(rng, t, start_us, cabin=motion == "ego_motion_cabin"))
    boxes = _annotations(rng, tables, sample_tokens, times, start_us)
    for sensor, calibration in zip(SENSORS, calibrations):
        _sensor_frames(rng, tables, files, sensor, calibration, sample_tokens, times, start_us, boxes)


def _motion(rng, t_us: int, start_us: int, *, cabin: bool) -> dict:
    s = (t_us - start_us) / 1e6
    wobble = 0.01 if cabin else 0.002  # the cabin sways on its suspension, the chassis hardly
    return {"token": random_tokens(rng, 1)[0], "timestamp": int(t_us), "vx": round(SPEED_M_S + 0.05 * s, 5),
            "vy": round(float(rng.normal(0, 0.02)), 5), "vz": 0.0, "ax": 0.1, "ay": round(0.4 * s * 0.033, 5),
            "az": round(float(rng.normal(0, 0.05)), 5), "yaw": round(0.033 * s, 6),
            "pitch": round(float(rng.normal(0, wobble)), 6), "roll": round(float(rng.normal(0, wobble)), 6),
            "yaw_rate": 0.033, "pitch_rate": round(float(rng.normal(0, wobble)), 6),
            "roll_rate": round(float(rng.normal(0, wobble)), 6)}


def _annotations(rng, tables, sample_tokens, times, start_us) -> dict[str, list[tuple]]:
    """Every object's annotations (sample token -> [(translation, size, rotation, category)]) for the pictures.
    The car is missing from the middle samples when there are 5 or more (a gap: NaN velocity around it); the
    pedestrian is annotated once only (a track of one)."""
    by_sample: dict[str, list[tuple]] = {token: [] for token in sample_tokens}
    attribute_tokens = {a: name_token("ts-attribute", a) for a in ATTRIBUTES}
    n = len(sample_tokens)
    for index, (category, attributes, offset, speed, size) in enumerate(OBJECTS):
        present = list(range(n))
        if category == "vehicle.car" and n >= 5:
            present = [k for k in present if k not in (2, 3, 4)]
        elif category == "human.pedestrian.adult":
            present = [min(1, n - 1)]
        instance_token = random_tokens(rng, 1)[0]
        tokens = random_tokens(rng, len(present))
        for j, k in enumerate(present):
            s = (times[k] - start_us) / 1e6 if speed else 0.0  # objects that stand keep their place in the world
            ego_xyz, ego_yaw = _ego(times[k] if speed else start_us, start_us)
            yaw = float(ego_yaw) + (0.0 if speed else 0.3 * index)
            local = np.array([offset[0] + (speed - SPEED_M_S) * s, offset[1]])
            c, si = np.cos(ego_yaw), np.sin(ego_yaw)
            xy = ego_xyz[:2] + np.array([c * local[0] - si * local[1], si * local[0] + c * local[1]])
            translation = [round(float(xy[0]), 4), round(float(xy[1]), 4), round(size[2] / 2 + rng.uniform(-.05, .05), 4)]
            rotation = [float(v) for v in quat_from_yaw(np.array([yaw]))[0]]
            visibility = "" if (index == 1 and j == 0) else str(1 + (index + j) % 4)  # one without a visibility
            tables["sample_annotation"].append({
                "token": tokens[j], "sample_token": sample_tokens[k], "instance_token": instance_token,
                "visibility_token": visibility, "attribute_tokens": [attribute_tokens[a] for a in attributes],
                "translation": translation, "size": list(size), "rotation": rotation,
                "prev": tokens[j - 1] if j else "", "next": tokens[j + 1] if j + 1 < len(present) else "",
                "num_lidar_pts": int(rng.integers(0, 400)), "num_radar_pts": int(rng.integers(0, 12))})
            by_sample[sample_tokens[k]].append((np.array(translation), np.array(size), np.array(rotation), category))
        tables["instance"].append({"token": instance_token, "category_token": name_token("ts-category", category),
                                   "nbr_annotations": len(present), "first_annotation_token": tokens[0],
                                   "last_annotation_token": tokens[-1]})
    return by_sample


def _sensor_frames(rng, tables, files, sensor, calibration, sample_tokens, times, start_us, boxes) -> None:
    """One keyframe per sample and one sweep before each keyframe but the first (pointing to the sample that
    follows, as in nuScenes), chained by prev/next."""
    channel, modality, _mount, _yaw, offset_us = sensor
    frames = []
    for k, sample_token in enumerate(sample_tokens):
        if k:
            frames.append((times[k] - INTERVAL_US // 2 + offset_us, sample_token, False))
        frames.append((times[k] + offset_us, sample_token, True))
    tokens = random_tokens(rng, len(frames))
    extension = {"camera": "jpg", "lidar": "pcd", "radar": "pcd"}[modality]
    for i, (t_us, sample_token, key) in enumerate(frames):
        pose_token = random_tokens(rng, 1)[0]
        translation, yaw = _ego(t_us, start_us)
        tables["ego_pose"].append({"token": pose_token, "timestamp": int(t_us),
                                   "rotation": [float(v) for v in quat_from_yaw(np.array([yaw]))[0]],
                                   "translation": [round(float(v), 6) for v in translation]})
        filename = f"{'samples' if key else 'sweeps'}/{channel}/{channel}_{t_us}.{extension}"
        tables["sample_data"].append({
            "token": tokens[i], "sample_token": sample_token, "ego_pose_token": pose_token,
            "calibrated_sensor_token": calibration["token"], "filename": filename, "fileformat": extension,
            "width": WIDTH if modality == "camera" else 0, "height": HEIGHT if modality == "camera" else 0,
            "timestamp": int(t_us), "is_key_frame": key, "next": tokens[i + 1] if i + 1 < len(frames) else "",
            "prev": tokens[i - 1] if i else ""})
        if modality == "camera":
            files[filename] = _image(rng)
        elif modality == "lidar":
            files[filename] = lidar_pcd(rng, t_us)
        else:
            files[filename] = radar_pcd(rng)


def _image(rng: np.random.Generator) -> bytes:
    """Sky over a road, with a little noise so that no two JPEGs are the same."""
    rows = np.linspace(0, 1, HEIGHT)[:, None, None]
    sky, road = np.array([235, 206, 170]), np.array([90, 96, 100])  # BGR
    image = np.where(rows < 0.5, sky, road) * np.ones((1, WIDTH, 1))
    image = np.clip(image + rng.normal(0, 4, image.shape), 0, 255).astype(np.uint8)
    ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 85])
    assert ok
    return jpeg.tobytes()


def pcd_bytes(fields: list[tuple[str, str, int]], data: np.ndarray) -> bytes:
    """A PCD v0.7 file with `DATA binary` (what pypcd4's `save` writes by default): `fields` as (name, TYPE,
    SIZE), `data` a structured array of those fields."""
    header = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
              f"FIELDS {' '.join(f[0] for f in fields)}\nSIZE {' '.join(str(f[2]) for f in fields)}\n"
              f"TYPE {' '.join(f[1] for f in fields)}\nCOUNT {' '.join('1' for _ in fields)}\n"
              f"WIDTH {len(data)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(data)}\nDATA binary\n")
    return header.encode("ascii") + data.tobytes()


LIDAR_FIELDS = [("x", "F", 4), ("y", "F", 4), ("z", "F", 4), ("intensity", "F", 4), ("timestamp", "U", 8)]
RADAR_FIELDS = [("x", "F", 4), ("y", "F", 4), ("z", "F", 4), ("vrel_x", "F", 4), ("vrel_y", "F", 4),
                ("vrel_z", "F", 4), ("rcs", "F", 4)]


def _dtype(fields) -> np.dtype:
    return np.dtype([(name, f"<{'f' if kind == 'F' else 'u'}{size}") for name, kind, size in fields])


def lidar_pcd(rng: np.random.Generator, t_us: int, points: int = 240) -> bytes:
    """A ring of ground points and a few close ones (inside the devkit's 1 m `remove_close` square), each with
    its own timestamp over the 100 ms sweep."""
    data = np.zeros(points, _dtype(LIDAR_FIELDS))
    angle = rng.uniform(-np.pi, np.pi, points)
    radius = np.where(np.arange(points) < 8, rng.uniform(0.2, 0.9, points), rng.uniform(2, 60, points))
    data["x"], data["y"] = radius * np.cos(angle), radius * np.sin(angle)
    data["z"] = rng.uniform(-2.2, 1.5, points)
    data["intensity"] = rng.uniform(0, 100, points).round(1)
    data["timestamp"] = t_us - 100_000 + np.sort(rng.integers(0, 100_000, points))
    return pcd_bytes(LIDAR_FIELDS, data)


def radar_pcd(rng: np.random.Generator, points: int = 40) -> bytes:
    data = np.zeros(points, _dtype(RADAR_FIELDS))
    for name, low, high in (("x", 1, 120), ("y", -30, 30), ("z", -1, 2), ("vrel_x", -20, 5), ("vrel_y", -3, 3),
                            ("vrel_z", -0.5, 0.5), ("rcs", -10, 30)):
        data[name] = rng.uniform(low, high, points)
    return pcd_bytes(RADAR_FIELDS, data)
