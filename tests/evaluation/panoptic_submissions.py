"""Seeded Panoptic nuScenes submissions for the devkit comparisons (tests/evaluation/test_panoptic_devkit.py),
written from the ground truth the devkit itself loads and maps, then perturbed to reach the evaluators' edges:
thing instances split in two, merged with another of their class, labelled as stuff, their identity switched
from one frame to the next; stuff labelled as a thing instance; fragments of classes the ground truth does not
hold; points flipped to random labels. Seed None: the perfect submission."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

META = {"use_camera": False, "use_lidar": True, "use_radar": False, "use_map": False, "use_external": False}
THINGS = range(1, 11)


def ground_truth(nusc, token: str) -> tuple[np.ndarray, np.ndarray]:
    """(raw panoptic labels, coarse classes by the devkit's own mapper) of lidar reading `token`."""
    from nuscenes.eval.panoptic.utils import PanopticClassMapper

    raw = np.load(Path(nusc.dataroot) / nusc.get("panoptic", token)["filename"])["data"].astype(np.int64)
    return raw, PanopticClassMapper(nusc).convert_label(raw // 1000)


def perfect(raw: np.ndarray, coarse: np.ndarray, rng) -> np.ndarray:
    """The ground truth as a prediction: class * 1000 + instance id for things, class * 1000 for stuff; the
    ignored points anything."""
    thing = (coarse >= 1) & (coarse <= 10)
    pred = coarse * 1000 + np.where(thing, raw % 1000, 0)
    ignored = coarse == 0
    return np.where(ignored, rng.integers(0, 17, len(raw)) * 1000 + rng.integers(0, 3, len(raw)), pred)


def perturbed(raw: np.ndarray, coarse: np.ndarray, rng, absent: list[int]) -> np.ndarray:
    pred = perfect(raw, coarse, rng)
    thing = (coarse >= 1) & (coarse <= 10)
    for label in np.unique(raw[thing]):
        points = np.flatnonzero(raw == label)
        cl = int(coarse[points[0]])
        action = rng.choice(["keep", "split", "merge", "as_stuff", "switch", "shrink"])
        if action == "split":  # two halves, neither over half the instance: a FN and up to two FPs
            pred[points[rng.random(len(points)) < 0.5]] = cl * 1000 + 500 + label % 100
        elif action == "merge":  # into the previous instance of its class
            others = np.unique(raw[(coarse == cl) & (raw != label) & thing])
            if len(others):
                pred[points] = cl * 1000 + int(others[0]) % 1000
        elif action == "as_stuff":  # a thing labelled as a stuff class
            pred[points] = int(rng.integers(11, 17)) * 1000
        elif action == "switch":  # another identity in this frame (an ID switch for its track)
            pred[points] = cl * 1000 + 900 + int(rng.integers(0, 50))
        elif action == "shrink":  # a third of it kept: IoU under 0.5
            pred[points[rng.random(len(points)) < 0.66]] = 11000
    stuff = np.flatnonzero(coarse >= 11)
    if len(stuff):  # stuff labelled as things: a run of ground points as one instance of a thing class
        start = int(rng.integers(0, len(stuff)))
        pred[stuff[start:start + int(rng.integers(5, 60))]] = int(rng.integers(1, 11)) * 1000 + 777
    for cl in absent:  # fragments of classes the ground truth does not hold: some under min_inst_points
        where = rng.choice(len(raw), int(rng.integers(3, 40)), replace=False)
        pred[where] = cl * 1000 + int(rng.integers(1, 5))
    flipped = rng.random(len(raw)) < 0.03
    pred[flipped] = rng.integers(0, 17, int(flipped.sum())) * 1000 + rng.integers(0, 3, int(flipped.sum()))
    return pred


def write(nusc, folder: Path, seed: int | None, *, split: str = "train", task: str | None = None,
          dtype=np.uint16) -> Path:
    """A submission for every keyframe LIDAR_TOP of the dataroot (seed None: perfect)."""
    rng = np.random.default_rng(0 if seed is None else seed)
    (folder / "panoptic" / split).mkdir(parents=True)
    (folder / split).mkdir()
    (folder / split / "submission.json").write_text(json.dumps({"meta": {**({"task": task} if task else {}),
                                                                         **META}}))
    frames = [sample["data"]["LIDAR_TOP"] for sample in nusc.sample]
    present = set()
    for token in frames:
        present |= set(np.unique(ground_truth(nusc, token)[1]).tolist())
    absent = [cl for cl in range(1, 17) if cl not in present]
    for token in frames:
        raw, coarse = ground_truth(nusc, token)
        pred = perfect(raw, coarse, rng) if seed is None else perturbed(raw, coarse, rng, absent[:2])
        np.savez_compressed(folder / "panoptic" / split / f"{token}_panoptic.npz", data=pred.astype(dtype))
    return folder
