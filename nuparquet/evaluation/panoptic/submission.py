"""A panoptic submission as nuscenes-devkit reads it (eval/panoptic/evaluate.py): per keyframe lidar reading
`<results>/panoptic/<split>/<token>_panoptic.npz` (its `data` array: one label per point, in the order of the
points of the reading's file, coarse class * 1000 + instance id) and `<results>/<split>/submission.json`
({"meta": {"task": "segmentation" | "tracking", "use_camera", "use_lidar", "use_radar", "use_map",
"use_external"}}: the devkit's `main` takes the task from it; the five flags are booleans as the lidarseg
challenge's `validate_submission` checks)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from nuparquet.errors import InputError
from nuparquet.evaluation.segmentation.submission import read_meta as segmentation_meta

DEVKIT_TASKS = ("segmentation", "tracking")


def read_meta(results: Path, split: str) -> dict:
    """The submission's meta ({"task"?: str, flag: bool}); UsageError when `results` is not a folder, InputError
    for a missing or malformed submission.json (the lidarseg reader's checks, with the devkit's optional task)."""
    return segmentation_meta(results, split, kind="panoptic", extra={"task": DEVKIT_TASKS},
                             missing="the submission's meta: task and the use_* flags")


def predictions_folder(results: Path, split: str) -> Path:
    folder = results / "panoptic" / split
    if not folder.is_dir():  # the devkit's own first assertion
        raise InputError(f"{folder} does not exist: the folder of the <lidar sample_data token>_panoptic.npz files")
    return folder


def read_predictions(folder: Path, token: str, num_points: int, num_classes: int) -> np.ndarray:
    """(P,) int64: the predicted panoptic labels of lidar reading `token`; InputError naming the file and the
    reading for a missing or unreadable file, no `data` array, one not of integers, a length other than its
    `num_points`, or a label whose class (label // 1000) is outside 0..num_classes-1 (the devkit would fail on
    a class above, and count a negative label as a class counted from the end)."""
    path = folder / f"{token}_panoptic.npz"
    if not path.is_file():
        raise InputError(f"{path} does not exist: the submission has no predictions for lidar sample_data {token}")
    try:
        with np.load(path) as archive:
            if "data" not in archive.files:
                raise InputError(f"{path}: no 'data' array (it holds {', '.join(archive.files) or 'none'}) for lidar "
                                 f"sample_data {token}")
            pred = archive["data"]
    except (zipfile.BadZipFile, ValueError, OSError) as exc:
        raise InputError(f"{path}: not a readable .npz file ({exc}) for lidar sample_data {token}") from None
    if pred.ndim != 1 or pred.dtype.kind not in "ui":
        raise InputError(f"{path}: 'data' is {pred.dtype} of shape {pred.shape} for lidar sample_data {token}, not "
                         "one integer label per point")
    if len(pred) != num_points:
        raise InputError(f"{path}: {len(pred)} predictions for lidar sample_data {token}, which has {num_points} "
                         "points")
    pred = pred.astype(np.int64)
    bad = np.flatnonzero((pred < 0) | (pred >= num_classes * 1000))
    if len(bad):
        raise InputError(f"{path}: label {int(pred[bad[0]])} at point {int(bad[0])} of lidar sample_data {token} "
                         f"has a class outside 0..{num_classes - 1} ({len(bad)} such points; a label is class * 1000 "
                         "+ instance id)")
    return pred
