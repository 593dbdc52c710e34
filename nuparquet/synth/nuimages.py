"""A deterministic nuImages-format dataroot (`nuparquet synth --format nuimages`): the ten tables that
`nuimages.NuImages` loads, real JPEGs, and masks drawn as polygons then RLE-encoded (`synth.coco_rle`).

    out/<version>/{attribute,calibrated_sensor,category,ego_pose,log,object_ann,sample,sample_data,sensor,
                   surface_ann}.json
    out/samples/<CHANNEL>/<log>__<CHANNEL>__<timestamp>.jpg     the annotated keyframes
    out/sweeps/<CHANNEL>/...                                   6 images before and 6 after each keyframe (2 Hz)

`scenes` logs, `samples_per_scene` samples each (one camera per sample, in turn). Every keyframe has objects of
the nuImages taxonomy (their attributes as nuImages requires per class), a driveable surface and, on the back
cameras, the ego vehicle; the cases the devkit treats apart are there too: an object and a surface without a mask
(null), an object touching the image's edges, a two-attribute emergency vehicle, integer speeds among floats and a
6-coefficient fisheye distortion. Same arguments, same bytes.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from nuparquet.atomic import atomic_directory
from nuparquet.rendering.palette import CATEGORY_RGB
from nuparquet.synth.coco_rle import encode
from nuparquet.synth.tokens import name_token, random_tokens

WIDTH, HEIGHT = 480, 270
AROUND = 6  # non-keyframe images before and after each keyframe
INTERVAL_US = 500_000
CAMERAS = ("CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_BACK_RIGHT", "CAM_BACK", "CAM_BACK_LEFT", "CAM_FRONT_LEFT")
LOCATIONS = ("singapore-onenorth", "boston-seaport", "singapore-queenstown", "singapore-hollandvillage")
# The nuImages taxonomy: 23 object classes with the attribute groups each must carry, then the two surfaces.
OBJECT_CLASSES = {
    "animal": ("pedestrian", "vertical_position"), "human.pedestrian.adult": ("pedestrian",),
    "human.pedestrian.child": ("pedestrian",), "human.pedestrian.construction_worker": ("pedestrian",),
    "human.pedestrian.personal_mobility": ("cycle",), "human.pedestrian.police_officer": ("pedestrian",),
    "human.pedestrian.stroller": (), "human.pedestrian.wheelchair": (), "movable_object.barrier": (),
    "movable_object.debris": (), "movable_object.pushable_pullable": (), "movable_object.trafficcone": (),
    "static_object.bicycle_rack": (), "vehicle.bicycle": ("cycle",), "vehicle.bus.bendy": ("vehicle",),
    "vehicle.bus.rigid": ("vehicle",), "vehicle.car": ("vehicle",), "vehicle.construction": ("vehicle",),
    "vehicle.emergency.ambulance": ("vehicle", "vehicle_light.emergency"),
    "vehicle.emergency.police": ("vehicle", "vehicle_light.emergency"), "vehicle.motorcycle": ("cycle",),
    "vehicle.trailer": ("vehicle",), "vehicle.truck": ("vehicle",),
}
SURFACE_CLASSES = ("flat.driveable_surface", "vehicle.ego")
ATTRIBUTES = ("cycle.with_rider", "cycle.without_rider", "pedestrian.moving", "pedestrian.sitting_lying_down",
              "pedestrian.standing", "vehicle.moving", "vehicle.parked", "vehicle.stopped",
              "vehicle_light.emergency.flashing", "vehicle_light.emergency.not_flashing",
              "vertical_position.off_ground", "vertical_position.on_ground")


def synthesize_nuimages(dataroot: Path, logs: int, samples_per_log: int, seed: int, version: str) -> Path:
    """Write the dataroot (tables atomically into `dataroot/version`, replacing it) and return `dataroot`."""
    rng = np.random.default_rng([seed, 40])
    tables = _vocabulary()
    for name in ("log", "calibrated_sensor", "sample", "sample_data", "ego_pose", "object_ann", "surface_ann"):
        tables[name] = []
    images: dict[str, np.ndarray] = {}
    start_us = 1_533_000_000_000_000
    for log_index in range(logs):
        log_token = random_tokens(rng, 1)[0]
        location = LOCATIONS[log_index % len(LOCATIONS)]
        date = f"2018-08-{1 + log_index % 28:02d}"
        logfile = f"n{8 + log_index % 2:03d}-{date}-12-00-00+0800"
        tables["log"].append({"token": log_token, "logfile": logfile, "vehicle": f"n{8 + log_index % 2:03d}",
                              "date_captured": date, "location": location})
        calibrations = {camera: _calibration(rng, camera, log_index) for camera in CAMERAS}
        tables["calibrated_sensor"] += calibrations.values()
        for sample_index in range(samples_per_log):
            camera = CAMERAS[(log_index + sample_index) % len(CAMERAS)]
            key_us = start_us + (log_index * 1000 + sample_index * 20) * 1_000_000
            _sample(rng, tables, images, log_token, logfile, camera, calibrations[camera]["token"], key_us,
                    first=log_index == 0 and sample_index == 0)
    with atomic_directory(dataroot / version, overwrite=True) as partial:
        for name, records in tables.items():
            with (partial / f"{name}.json").open("w") as out:
                json.dump(records, out, indent=2)
    for filename, image in images.items():
        path = dataroot / filename
        path.parent.mkdir(parents=True, exist_ok=True)
        ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
        path.write_bytes(jpeg.tobytes())
    return dataroot


def _vocabulary() -> dict[str, list[dict]]:
    return {
        "category": [{"token": name_token("category", n), "name": n, "description": f"nuImages class {n}."}
                     for n in (*OBJECT_CLASSES, *SURFACE_CLASSES)],
        "attribute": [{"token": name_token("attribute", n), "name": n, "description": f"Attribute {n}."}
                      for n in ATTRIBUTES],
        "sensor": [{"token": name_token("sensor", c), "channel": c, "modality": "camera"} for c in CAMERAS],
    }


def _calibration(rng: np.random.Generator, camera: str, log_index: int) -> dict:
    yaw = np.deg2rad({"CAM_FRONT": 0, "CAM_FRONT_RIGHT": -55, "CAM_BACK_RIGHT": -110, "CAM_BACK": 180,
                      "CAM_BACK_LEFT": 110, "CAM_FRONT_LEFT": 55}[camera])
    # camera z forward, x right, y down: rotate the ego frame's axes onto the camera's, then the yaw
    half = yaw / 2
    q_yaw = np.array([np.cos(half), 0, 0, np.sin(half)])
    q_axes = np.array([0.5, -0.5, 0.5, -0.5])
    w1, x1, y1, z1 = q_yaw
    w2, x2, y2, z2 = q_axes
    rotation = [w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2]
    focal = round(float(400 + rng.uniform(-5, 5)), 6)
    fisheye = camera == "CAM_BACK" and log_index % 2 == 1
    distortion = [round(float(v), 8) for v in rng.normal(0, 0.05, 6 if fisheye else 5)]
    return {"token": random_tokens(rng, 1)[0], "sensor_token": name_token("sensor", camera),
            "translation": [round(float(v), 4) for v in (1.5 * np.cos(yaw), 0.8 * np.sin(yaw), 1.55)],
            "rotation": [float(v) for v in rotation],
            "camera_intrinsic": [[focal, 0.0, WIDTH / 2], [0.0, focal, HEIGHT / 2], [0.0, 0.0, 1.0]],
            "camera_distortion": distortion}


def _sample(rng, tables, images, log_token, logfile, camera, calibration_token, key_us, *, first: bool) -> None:
    sample_token, *frame_tokens = random_tokens(rng, 2 + 2 * AROUND)
    key = AROUND
    heading = rng.uniform(-np.pi, np.pi)
    origin = rng.uniform(-500, 500, 2)
    for i, token in enumerate(frame_tokens):
        t_us = key_us + (i - key) * INTERVAL_US
        pose_token = random_tokens(rng, 1)[0]
        speed = 0 if i < 2 else round(float(rng.uniform(2, 9)), 3)  # stopped (an integer 0) then driving
        yaw = heading + 0.01 * i
        tables["ego_pose"].append({
            "token": pose_token, "timestamp": t_us,
            "rotation": [float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2))],
            "translation": [round(float(origin[0] + 3 * i * np.cos(heading)), 3),
                            round(float(origin[1] + 3 * i * np.sin(heading)), 3), 0.0],
            "rotation_rate": [round(float(v), 5) for v in rng.normal(0, 0.02, 3)],
            "acceleration": [round(float(v), 4) for v in rng.normal(0, 0.3, 3)], "speed": speed})
        folder = "samples" if i == key else "sweeps"
        filename = f"{folder}/{camera}/{logfile}__{camera}__{t_us}.jpg"
        tables["sample_data"].append({
            "token": token, "sample_token": sample_token, "ego_pose_token": pose_token,
            "calibrated_sensor_token": calibration_token, "filename": filename, "fileformat": "jpg",
            "width": WIDTH, "height": HEIGHT, "timestamp": t_us, "is_key_frame": i == key,
            "next": frame_tokens[i + 1] if i + 1 < len(frame_tokens) else "",
            "prev": frame_tokens[i - 1] if i > 0 else ""})
        images[filename] = _background(rng)
    tables["sample"].append({"token": sample_token, "timestamp": key_us, "log_token": log_token,
                             "key_camera_token": frame_tokens[key]})
    key_image = images[tables["sample_data"][-len(frame_tokens) + key]["filename"]]
    _annotate(rng, tables, key_image, frame_tokens[key], camera, first=first)


def _background(rng: np.random.Generator) -> np.ndarray:
    sky = np.linspace(200, 120, HEIGHT, dtype=np.float64)[:, None, None] * np.array([1.0, 0.95, 0.85])
    image = np.broadcast_to(sky, (HEIGHT, WIDTH, 3)).copy()
    image += rng.normal(0, 4, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8)


def _polygon(rng: np.random.Generator, centre, radius) -> np.ndarray:
    """A star-shaped polygon around `centre` ((x, y) pixels), integer vertices."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, 9))
    r = radius * rng.uniform(0.6, 1.0, (9, 1))
    return np.round(centre + r * np.stack([np.cos(angles), np.sin(angles)], 1)).astype(np.int32)


def _paint(image_bgr: np.ndarray, polygon: np.ndarray, name: str) -> np.ndarray:
    mask = np.zeros((HEIGHT, WIDTH), np.uint8)
    cv2.fillPoly(mask, [polygon], 1)
    r, g, b = (int(0.6 * v) for v in CATEGORY_RGB.get(name, (128, 128, 128)))  # darker: an overlay shows on it
    image_bgr[mask == 1] = (b, g, r)
    return mask


def _annotate(rng, tables, image, sd_token, camera, *, first: bool) -> None:
    road = np.array([[0, HEIGHT - 1], [WIDTH // 2 - 40, HEIGHT // 2], [WIDTH // 2 + 40, HEIGHT // 2],
                     [WIDTH - 1, HEIGHT - 1]], np.int32)
    surfaces = [("flat.driveable_surface", road)]
    if camera.startswith("CAM_BACK"):
        surfaces.append(("vehicle.ego", np.array([[60, HEIGHT - 1], [120, HEIGHT - 25], [WIDTH - 120, HEIGHT - 25],
                                                   [WIDTH - 60, HEIGHT - 1]], np.int32)))
    for i, (name, polygon) in enumerate(surfaces):
        mask = _paint(image, polygon, name)
        tables["surface_ann"].append({"token": random_tokens(rng, 1)[0], "sample_data_token": sd_token,
                                      "category_token": name_token("category", name),
                                      "mask": None if first and i == 0 else encode(mask)})
    classes = list(OBJECT_CLASSES)
    n = int(rng.integers(3, 7))
    picks = [classes[int(k)] for k in rng.integers(0, len(classes), n)]
    if first:  # the cases the devkit treats apart, in the first image
        picks[:2] = ["vehicle.emergency.police", "vehicle.car"]
    for j, name in enumerate(picks):
        centre = rng.uniform([40, 60], [WIDTH - 40, HEIGHT - 40])
        if first and j == 1:
            centre = np.array([10.0, 10.0])  # runs over the top-left edges
        mask = _paint(image, _polygon(rng, centre, rng.uniform(15, 45)), name)
        ys, xs = np.nonzero(mask)
        bbox = [int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max())]
        attributes = [name_token("attribute", _attribute(rng, group)) for group in OBJECT_CLASSES[name]]
        tables["object_ann"].append({
            "token": random_tokens(rng, 1)[0], "sample_data_token": sd_token,
            "category_token": name_token("category", name), "attribute_tokens": attributes, "bbox": bbox,
            "mask": None if first and j == len(picks) - 1 else encode(mask)})


def _attribute(rng: np.random.Generator, group: str) -> str:
    choices = [a for a in ATTRIBUTES if a.startswith(group + ".")]
    return choices[int(rng.integers(0, len(choices)))]
