"""Edits of a synthetic dataroot's JSON that give the evaluation's hard cases ground truth to work on (the
generator's data lacks them): bicycles in bicycle racks (and one just outside), boxes exactly at a class range,
two ground-truth boxes at one spot (listed in sample_annotation.json in the opposite order of their instance
tokens, so only the JSON order tells which a prediction takes), annotations without an attribute or without
points, and classes without any ground truth in the evaluated split. The devkit reads the edited JSON; so does
the conversion."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from pyquaternion import Quaternion

from nuscenes.utils.splits import create_splits_scenes

GONE_CLASSES = ("vehicle.trailer", "vehicle.construction")  # no ground truth left in the split: no-GT classes


def _load(folder: Path, name: str) -> list[dict]:
    return json.loads((folder / f"{name}.json").read_text())


def _save(folder: Path, name: str, records: list[dict]) -> None:
    (folder / f"{name}.json").write_text(json.dumps(records, indent=0))


def _token(prefix: str, i: int) -> str:
    return (prefix + f"{i:x}").ljust(32, "0")[:32]


def _exact_offset(x: float, offset: float) -> float | None:
    """A float v with v - x == offset exactly (float64), or None where x + offset is not representable."""
    value = x + offset
    return float(value) if value - x == offset else None


def edit_dataset(root: Path, version: str, split: str = "val") -> dict:
    """Apply the edits to `root/version` in place; returns what was done (tokens), for the tests' preconditions."""
    folder = root / version
    tables = {name: _load(folder, name) for name in ("sample_annotation", "instance", "category", "attribute",
                                                     "sample", "sample_data", "ego_pose", "scene", "calibrated_sensor",
                                                     "sensor")}
    split_scenes = set(create_splits_scenes()[split])
    scene_name = {s["token"]: s["name"] for s in tables["scene"]}
    sample = {s["token"]: s for s in tables["sample"]}
    in_split = {t for t, s in sample.items() if scene_name[s["scene_token"]] in split_scenes}
    category_of_name = {c["name"]: c["token"] for c in tables["category"]}
    category_name = {c["token"]: c["name"] for c in tables["category"]}
    instance = {i["token"]: i for i in tables["instance"]}
    attribute = {a["name"]: a["token"] for a in tables["attribute"]}
    lidar_sensor = {s["token"] for s in tables["sensor"] if s["channel"] == "LIDAR_TOP"}
    lidar_calibration = {c["token"] for c in tables["calibrated_sensor"] if c["sensor_token"] in lidar_sensor}
    ego_pose = {e["token"]: e for e in tables["ego_pose"]}
    ego_of_sample = {d["sample_token"]: ego_pose[d["ego_pose_token"]]["translation"] for d in tables["sample_data"]
                     if d["is_key_frame"] and d["calibrated_sensor_token"] in lidar_calibration}
    anns = tables["sample_annotation"]
    done: dict = {"racks": [], "in_rack": [], "outside_rack": [], "at_range": [], "duplicates": [], "no_attribute": [],
                  "no_points": []}

    def cat(a):
        return category_name[instance[a["instance_token"]]["category_token"]]

    split_anns = [a for a in anns if a["sample_token"] in in_split]
    # 1. classes without ground truth: their split instances become ambulances (not a detection class)
    for a in split_anns:
        if cat(a) in GONE_CLASSES:
            instance[a["instance_token"]]["category_token"] = category_of_name["vehicle.emergency.ambulance"]
    # 2. bicycle racks: a new rack around a bicycle (centre inside) in three samples, one more just missing a cycle
    new_instances, new_anns, counter = [], [], [0]

    def add(sample_token: str, category: str, translation, size, yaw: float, *, attributes=(), num_lidar=20,
            before: str | None = None, instance_prefix: str = "e0") -> str:
        counter[0] += 1
        inst = _token(instance_prefix, counter[0])
        token = _token("a0", counter[0])
        new_instances.append({"token": inst, "category_token": category_of_name[category], "nbr_annotations": 1,
                              "first_annotation_token": token, "last_annotation_token": token})
        record = {"token": token, "sample_token": sample_token, "instance_token": inst, "visibility_token": "4",
                  "attribute_tokens": list(attributes), "translation": [float(v) for v in translation],
                  "size": [float(v) for v in size],
                  "rotation": Quaternion(axis=[0, 0, 1], angle=yaw).elements.tolist(), "prev": "", "next": "",
                  "num_lidar_pts": num_lidar, "num_radar_pts": 0}
        new_anns.append((before, record))
        return token

    def near(a, limit_m=35.0):
        ex, ey, _ = ego_of_sample[a["sample_token"]]
        return np.hypot(a["translation"][0] - ex, a["translation"][1] - ey) < limit_m

    cycles = [a for a in split_anns if cat(a) in ("vehicle.bicycle", "vehicle.motorcycle")
              and a["num_lidar_pts"] + a["num_radar_pts"] > 0 and near(a)]  # kept but for the rack
    seen_samples = set()
    for a in cycles:
        if a["sample_token"] in seen_samples or len(done["in_rack"]) >= 3:
            continue
        seen_samples.add(a["sample_token"])
        x, y, z = a["translation"]
        done["racks"].append(add(a["sample_token"], "static_object.bicycle_rack", (x + 0.4, y - 0.3, z),
                                 (2.0, 5.0, 1.2), 0.3))
        done["in_rack"].append(a["token"])
    # racks (yaw 0: length along x, width along y) that miss a cycle's centre by 5 cm along one axis each
    misses = iter(((-2.55, 0.0, 0.0), (0.0, 1.05, 0.0), (0.0, 0.0, 0.65)))
    for a in cycles:
        if a["sample_token"] in seen_samples:
            continue
        offset = next(misses, None)
        if offset is None:
            break
        seen_samples.add(a["sample_token"])
        x, y, z = a["translation"]
        done["racks"].append(add(a["sample_token"], "static_object.bicycle_rack",
                                 (x + offset[0], y + offset[1], z + offset[2]), (2.0, 5.0, 1.2), 0.0))
        done["outside_rack"].append(a["token"])
    # 3. ground truth exactly at the class range (dx exact, dy = 0): 40 m pedestrian, 50 m car (left out), and
    #    a car a hair inside 50 m (kept)
    def representable(a, distance):
        return _exact_offset(ego_of_sample[a["sample_token"]][0], distance) is not None

    peds = [a for a in split_anns if cat(a) == "human.pedestrian.adult" and a["num_lidar_pts"] > 0
            and representable(a, 40.0)]
    cars = [a for a in split_anns if cat(a) == "vehicle.car" and a["num_lidar_pts"] > 0 and representable(a, 50.0)]
    for a, distance, inside in ((peds[0], 40.0, False), (cars[0], 50.0, False), (cars[1], 50.0, True)):
        ex, ey, _ = ego_of_sample[a["sample_token"]]
        x = _exact_offset(ex, distance)
        if inside:
            x = np.nextafter(x, -np.inf)
        a["translation"] = [float(x), float(ey), a["translation"][2]]
        done["at_range"].append((a["token"], inside))
    # 4. a second box at exactly the spot of a car (bigger, other attribute), listed before it in the JSON; its
    #    instance token sorts after the car's in two samples and before it in one
    used = {a["sample_token"] for a in cars[:2]}
    cars = [a for a in split_anns if cat(a) == "vehicle.car" and a["num_lidar_pts"] > 0]
    for i, a in enumerate([c for c in cars if c["sample_token"] not in used][2:8:2]):
        size = [s * 1.4 for s in a["size"]]
        attributes = [attribute["vehicle.parked"]] if attribute["vehicle.parked"] not in a["attribute_tokens"] \
            else [attribute["vehicle.moving"]]
        token = add(a["sample_token"], "vehicle.car", a["translation"], size, 0.5, attributes=attributes,
                    before=a["token"], instance_prefix="0" if i == 2 else "f")
        done["duplicates"].append((token, a["token"]))
    # 5. annotations without attribute, and without points
    for a in [c for c in split_anns if cat(c) in ("vehicle.car", "human.pedestrian.adult")][5:40:7]:
        if a["token"] not in {d[1] for d in done["duplicates"]}:
            a["attribute_tokens"] = []
            done["no_attribute"].append(a["token"])
    for a in [c for c in split_anns if cat(c) == "vehicle.car"][8:30:11]:
        a["num_lidar_pts"], a["num_radar_pts"] = 0, 0
        done["no_points"].append(a["token"])
    # write: new annotations before their anchor (or at the end), new instances at the end
    out = []
    before = {}
    for anchor, record in new_anns:
        before.setdefault(anchor, []).append(record)
    for a in anns:
        out.extend(before.get(a["token"], []))
        out.append(a)
    out.extend(before.get(None, []))
    _save(folder, "sample_annotation", out)
    _save(folder, "instance", list(instance.values()) + new_instances)
    return done

