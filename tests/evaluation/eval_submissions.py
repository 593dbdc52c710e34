"""Submissions made from the ground truth (read through the devkit, independently of our Parquet) by
controlled perturbations."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from pyquaternion import Quaternion

from nuscenes.eval.detection.constants import ATTRIBUTE_NAMES, DETECTION_NAMES
from nuscenes.eval.detection.utils import category_to_detection_name, detection_name_to_rel_attributes
from nuscenes.utils.splits import create_splits_scenes

META = {"use_camera": False, "use_lidar": True, "use_radar": False, "use_map": False, "use_external": False}


def split_samples(nusc, split: str = "val") -> list[dict]:
    scenes = set(create_splits_scenes()[split])
    return [s for s in nusc.sample if nusc.get("scene", s["scene_token"])["name"] in scenes]


def ground_truth_boxes(nusc, sample: dict) -> list[dict]:
    """The sample's detection-class annotations as submission boxes (score 1), each with its "token"."""
    attributes = {a["token"]: a["name"] for a in nusc.attribute}
    boxes = []
    for token in sample["anns"]:
        ann = nusc.get("sample_annotation", token)
        name = category_to_detection_name(ann["category_name"])
        if name is None:
            continue
        boxes.append({"sample_token": sample["token"], "translation": list(ann["translation"]),
                      "size": list(ann["size"]), "rotation": list(ann["rotation"]),
                      "velocity": [float(v) for v in nusc.box_velocity(token)[:2]], "detection_name": name,
                      "detection_score": 1.0,
                      "attribute_name": attributes[ann["attribute_tokens"][0]] if ann["attribute_tokens"] else "",
                      "token": token})
    return boxes


def ego_position(nusc, sample: dict) -> list[float]:
    lidar = nusc.get("sample_data", sample["data"]["LIDAR_TOP"])
    return nusc.get("ego_pose", lidar["ego_pose_token"])["translation"]


def write(path: Path, results: dict, meta: dict | None = None) -> Path:
    for boxes in results.values():
        for box in boxes:
            box.pop("token", None)
    path.write_text(json.dumps({"meta": META if meta is None else meta, "results": results}))
    return path


def perfect(nusc, split: str = "val") -> dict:
    """Every ground-truth box as a prediction, all with score 1 (ties everywhere), NaN velocities kept."""
    return {s["token"]: ground_truth_boxes(nusc, s) for s in split_samples(nusc, split)}


def _yawed(rotation, angle: float) -> list[float]:
    return (Quaternion(rotation) * Quaternion(axis=[0, 0, 1], angle=angle)).elements.tolist()


def noisy(nusc, seed: int, split: str = "val") -> dict:
    """Shifted, rotated and rescaled boxes, velocity noise (some NaN), wrong attributes, class confusions,
    missed boxes, duplicates, false positives, scores on a 0.05 grid (ties), no bus at all (a class with ground
    truth but no prediction), trailers only as false positives (a class without ground truth)."""
    rng = np.random.default_rng(seed)
    results = {}
    for sample in split_samples(nusc, split):
        boxes = []
        for box in ground_truth_boxes(nusc, sample):
            if rng.uniform() < 0.12:
                continue  # missed
            box = dict(box)
            shift = rng.normal(0, 0.4, 3) * (4.0 if rng.uniform() < 0.15 else 1.0)
            box["translation"] = (np.array(box["translation"]) + shift).tolist()
            box["rotation"] = _yawed(box["rotation"], float(rng.normal(0, 0.6)))
            box["size"] = (np.array(box["size"]) * rng.uniform(0.7, 1.3, 3)).tolist()
            velocity = np.nan_to_num(np.array(box["velocity"])) + rng.normal(0, 0.5, 2)
            box["velocity"] = [float("nan")] * 2 if rng.uniform() < 0.1 else velocity.tolist()
            if rng.uniform() < 0.25:
                box["attribute_name"] = str(rng.choice(ATTRIBUTE_NAMES))
            elif box["attribute_name"] == "" and detection_name_to_rel_attributes(box["detection_name"]):
                box["attribute_name"] = detection_name_to_rel_attributes(box["detection_name"])[0]
            if rng.uniform() < 0.08:
                box["detection_name"] = str(rng.choice(DETECTION_NAMES))
            box["detection_score"] = float(np.round(rng.uniform(0.05, 1.0) / 0.05) * 0.05)
            boxes.append(box)
            if rng.uniform() < 0.08:  # a duplicate, nearby, usually lower score
                twin = dict(box, translation=(np.array(box["translation"]) + rng.normal(0, 0.3, 3)).tolist(),
                            detection_score=float(np.round(rng.uniform(0.05, box["detection_score"]) / 0.05) * 0.05))
                boxes.append(twin)
        ego = np.array(ego_position(nusc, sample))
        for _ in range(6):  # false positives around the ego vehicle
            boxes.append({"sample_token": sample["token"],
                          "translation": (ego + np.r_[rng.uniform(-55, 55, 2), 0.5]).tolist(),
                          "size": rng.uniform(0.5, 5, 3).tolist(), "rotation": _yawed([1, 0, 0, 0], rng.uniform(-3, 3)),
                          "velocity": rng.normal(0, 2, 2).tolist(), "detection_name": str(rng.choice(DETECTION_NAMES)),
                          "detection_score": float(np.round(rng.uniform(0, 1) / 0.05) * 0.05),
                          "attribute_name": ""})
        boxes = [b for b in boxes if b["detection_name"] != "bus"]
        order = rng.permutation(len(boxes))
        results[sample["token"]] = [boxes[i] for i in order]
    return results


def exact_offset(x: float, offset: float) -> float | None:
    """A float v with v - x == offset exactly (float64), or None where x + offset is not representable."""
    value = x + offset
    return float(value) if value - x == offset else None


def edge_cases(nusc, edits: dict, split: str = "val", thresholds=(0.5, 1.0, 2.0, 4.0)) -> tuple[dict, dict]:
    """Predictions exactly at the matching thresholds (dx exact, dy = 0) and a hair inside; exactly at a class
    range from the ego vehicle and a hair inside; bicycles in racks; a box claiming 0 points; two equal-score
    predictions on the two ground-truth boxes at one spot; and samples without any prediction. Returns the
    results and what was placed where (for the tests' preconditions)."""
    placed = {"at_threshold": [], "at_range": [], "in_rack": [], "on_duplicates": []}
    in_rack = set(edits["in_rack"]) | set(edits["outside_rack"])
    duplicates = {token for pair in edits["duplicates"] for token in pair}
    results = {}
    for index, sample in enumerate(split_samples(nusc, split)):
        boxes = []
        if index % 5 == 4:
            results[sample["token"]] = []  # nothing detected here
            continue
        gt = ground_truth_boxes(nusc, sample)
        for i, box in enumerate(gt):
            box = dict(box)
            token = box["token"]
            if token in in_rack:  # a prediction at a cycle in (or just outside) a rack
                box["detection_score"] = 0.9
                boxes.append(box)
                placed["in_rack"].append(token)
                continue
            if token in duplicates:
                box["detection_score"] = 0.7  # equal scores: the later box goes first; equal distances: the first gt
                boxes.append(box)
                placed["on_duplicates"].append(token)
                continue
            threshold = thresholds[i % len(thresholds)]
            x = exact_offset(box["translation"][0], threshold)
            if x is None:  # not representable: an ordinary prediction, 0.3 m off
                box["translation"] = [box["translation"][0] + 0.3, *box["translation"][1:]]
                box["detection_score"] = 0.33
                boxes.append(box)
                continue
            if i % 3 == 1:
                x = float(np.nextafter(x, -np.inf))  # a hair inside
            box["translation"] = [float(x), box["translation"][1], box["translation"][2]]
            box["detection_score"] = float(0.1 + 0.8 * ((i * 7) % 11) / 11)
            boxes.append(box)
            placed["at_threshold"].append((token, threshold, i % 3 != 1))
        ego = ego_position(nusc, sample)
        for distance, name in ((50.0, "car"), (40.0, "pedestrian"), (30.0, "barrier")):
            for inside in (False, True):
                x = exact_offset(ego[0], distance)
                if x is None:
                    continue
                if inside:
                    x = float(np.nextafter(x, -np.inf))
                boxes.append({"sample_token": sample["token"], "translation": [float(x), ego[1], ego[2]],
                              "size": [1.0, 2.0, 1.5], "rotation": [1.0, 0.0, 0.0, 0.0], "velocity": [0.0, 0.0],
                              "detection_name": name, "detection_score": 0.55, "attribute_name": ""})
                placed["at_range"].append((sample["token"], name, inside))
        if gt:
            claim = dict(gt[0], detection_score=0.95, num_pts=0)  # the devkit reads num_pts: filtered out
            boxes.append(claim)
        results[sample["token"]] = boxes
    return results, placed
