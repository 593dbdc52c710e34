"""Tracking submissions made from the ground truth (read through the devkit, independently of our Parquet) by
seeded perturbations that reach the evaluation's edges: tracks that split (a new id half-way), merge (an id taken
over by another object of the class), swap identities, leave (boxes pushed beyond the match distance) and come
back, start late, or are never found; ids given two classes along a track; gaps in a predicted track (the devkit
interpolates them); scores on a coarse grid (ties, thresholds reached by several recall levels); hypotheses at
exactly the spot of another (equal costs: the assignment solver's tie); false-positive tracks, predictions of a
class without ground truth, a class without predictions, a class predicted perfectly, and samples left empty."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np

from nuscenes.eval.tracking.utils import category_to_tracking_name
from nuscenes.utils.splits import create_splits_scenes

META = {"use_camera": False, "use_lidar": True, "use_radar": False, "use_map": False, "use_external": False}
BEHAVIOURS = ("good", "split", "merge", "swap", "leave", "late", "gap", "missing", "relabel")


def scene_tracks(nusc, split: str = "val") -> tuple[list[dict], dict]:
    """The split's samples (scene order, then time) and {scene token: {instance: [(sample index, annotation)]}}."""
    names = set(create_splits_scenes()[split])
    samples, tracks = [], {}
    for scene in nusc.scene:
        if scene["name"] not in names:
            continue
        token, mine = scene["first_sample_token"], defaultdict(list)
        while token:
            sample = nusc.get("sample", token)
            for ann_token in sample["anns"]:
                ann = nusc.get("sample_annotation", ann_token)
                if category_to_tracking_name(ann["category_name"]) is not None:
                    mine[ann["instance_token"]].append((len(samples), ann))
            samples.append(sample)
            token = sample["next"]
        tracks[scene["token"]] = mine
    return samples, tracks


def _box(sample, ann, name, tracking_id, score, offset=(0.0, 0.0)) -> dict:
    x, y, z = ann["translation"]
    return {"sample_token": sample["token"], "translation": [x + offset[0], y + offset[1], z],
            "size": list(ann["size"]), "rotation": list(ann["rotation"]), "velocity": [0.0, 0.0],
            "tracking_id": tracking_id, "tracking_name": name, "tracking_score": score}


def edge_submission(nusc, seed: int, *, split: str = "val", no_predictions: str = "bus",
                    perfect: str = "bicycle", without_gt: str = "trailer") -> dict:
    """results {sample token: [box, ...]} with every case of the module docstring, drawn with `seed`."""
    rng = np.random.default_rng(seed)
    samples, tracks = scene_tracks(nusc, split)
    results = {s["token"]: [] for s in samples}
    grid = (0.2, 0.4, 0.6, 0.8)
    for scene_token, instances in tracks.items():
        by_class = defaultdict(list)
        for instance, anns in instances.items():
            by_class[category_to_tracking_name(anns[0][1]["category_name"])].append(instance)
        swapped = {}
        for name, members in by_class.items():
            if name == no_predictions:
                continue
            for instance in members:
                anns = instances[instance]
                base = instance[:10]
                if name == perfect:
                    for i, ann in anns:
                        results[samples[i]["token"]].append(_box(samples[i], ann, name, base, 0.9))
                    continue
                behaviour = BEHAVIOURS[int(rng.integers(len(BEHAVIOURS)))]
                score = float(rng.choice(grid))
                jitter = rng.random() < 0.4  # per-box scores: the track's mean decides
                noise = rng.normal(0, 0.35, (len(anns), 2))
                half = len(anns) // 2
                partner = None
                if behaviour == "merge":  # another object's id, the earlier one of the class
                    others = [m for m in members if m != instance]
                    partner = others[int(rng.integers(len(others)))][:10] if others else None
                if behaviour == "swap" and instance not in swapped:
                    others = [m for m in members if m != instance and m not in swapped]
                    if others:  # from one sample on, the two objects carry each other's id
                        other = others[int(rng.integers(len(others)))]
                        start = anns[half][0]
                        swapped[instance], swapped[other] = (other[:10], start), (base, start)
                for k, (i, ann) in enumerate(anns):
                    tracking_id, offset, box_name = base, noise[k], name
                    if behaviour == "missing" or (behaviour == "late" and k < 2):
                        continue
                    if behaviour == "gap" and 0 < k < len(anns) - 1 and k % 2:
                        continue
                    if behaviour == "split" and k >= half:
                        tracking_id = base + "-b"
                    if behaviour == "merge" and partner is not None and k >= half:
                        tracking_id = partner
                    if instance in swapped and i >= swapped[instance][1]:
                        tracking_id = swapped[instance][0]
                    if behaviour == "leave" and 0 < k < len(anns) - 1:
                        offset = offset + np.array([2.6, 0.0])  # beyond the 2 m match distance
                    if behaviour == "relabel" and k == half:
                        box_name = "truck" if name != "truck" else "car"
                    box_score = float(np.clip(score + rng.normal(0, 0.05), 0.01, 0.99)) if jitter else score
                    results[samples[i]["token"]].append(_box(samples[i], ann, box_name, tracking_id, box_score,
                                                             tuple(offset)))
                    if rng.random() < 0.06:  # a twin at exactly the same spot: equal costs
                        results[samples[i]["token"]].append(_box(samples[i], ann, box_name, base + "-twin", score,
                                                                 tuple(offset)))
        # false-positive tracks near objects, and a class without ground truth
        for n_fp in range(3):
            instance = list(instances)[int(rng.integers(len(instances)))]
            anns = instances[instance]
            name = category_to_tracking_name(anns[0][1]["category_name"])
            if name in (no_predictions, perfect):
                continue
            for i, ann in anns:
                results[samples[i]["token"]].append(_box(samples[i], ann, name, f"fp{n_fp}-{instance[:6]}", 0.2,
                                                         (1.2, -0.9)))
        i, ann = next(iter(instances.values()))[0]
        results[samples[i]["token"]].append(_box(samples[i], ann, without_gt, f"lonely-{scene_token[:6]}", 0.5))
    # empty samples: every box of two samples without the perfect class removed (their keys stay, as the devkit
    # requires)
    perfect_samples = {samples[i]["token"] for instances in tracks.values() for anns in instances.values()
                       for i, ann in anns if category_to_tracking_name(ann["category_name"]) == perfect}
    for s in [s for s in samples if s["token"] not in perfect_samples][1::5][:2]:
        results[s["token"]] = []
    # an id given twice in one sample (a merge onto an object still there) is not a valid submission: keep the first
    for token, boxes in results.items():
        seen = set()
        results[token] = [b for b in boxes if not (b["tracking_id"] in seen or seen.add(b["tracking_id"]))]
    return results


def write(path: Path, results: dict, meta: dict | None = None) -> Path:
    path.write_text(json.dumps({"meta": META if meta is None else meta, "results": results}))
    return path
