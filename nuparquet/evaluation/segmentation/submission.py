"""A lidar segmentation submission as nuscenes-devkit reads it: `<results>/<split>/submission.json`
({"meta": {"use_camera", "use_lidar", "use_radar", "use_map", "use_external"}: booleans, exactly those keys, as
`validate_submission` checks) and per keyframe lidar reading `<results>/lidarseg/<split>/<token>_lidarseg.bin`
(uint8, one coarse class 1..16 per point, in the order of the points of the reading's file)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from nuparquet.errors import InputError, UsageError

META_KEYS = ("use_camera", "use_lidar", "use_radar", "use_map", "use_external")


def read_meta(results: Path, split: str, *, kind: str = "lidarseg", extra: dict | None = None,
              missing: str = "the devkit's validate_submission requires it") -> dict:
    """The submission's meta ({key: bool}, and the `extra` keys found); UsageError when `results` is not a folder,
    InputError for a missing or malformed submission.json. `kind`: the task's folder name (lidarseg, panoptic);
    `extra`: optional keys beside META_KEYS, each with the values it may take."""
    extra = extra or {}
    if not results.is_dir():
        raise UsageError(f"--results {results}: a {kind} submission is a folder holding {kind}/{split}/ and "
                         f"{split}/submission.json")
    path = results / split / "submission.json"
    if not path.is_file():
        raise InputError(f"{path} does not exist ({missing})")
    try:
        content = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: cannot be read as JSON ({exc})") from exc
    meta = content.get("meta") if isinstance(content, dict) else None
    if not isinstance(meta, dict) or set(meta) - set(extra) != set(META_KEYS):
        optional = f" (and optionally {', '.join(extra)})" if extra else ""
        raise InputError(f"{path}: \"meta\" must hold exactly {', '.join(META_KEYS)}{optional}")
    for key, allowed in extra.items():
        if key in meta and meta[key] not in allowed:
            raise InputError(f"{path}: meta.{key} must be one of {', '.join(allowed)}, not {meta[key]!r}")
    for key in META_KEYS:
        if type(meta[key]) is not bool:
            raise InputError(f"{path}: meta.{key} must be true or false, not {meta[key]!r}")
    return {key: meta[key] for key in (*extra, *META_KEYS) if key in meta}


def predictions_folder(results: Path, split: str) -> Path:
    folder = results / "lidarseg" / split
    if not folder.is_dir():
        raise InputError(f"{folder} does not exist: the folder of the <lidar sample_data token>_lidarseg.bin files")
    return folder


def read_predictions(folder: Path, token: str, num_points: int, num_classes: int) -> np.ndarray:
    """(P,) uint8: the predicted classes of lidar reading `token`; InputError naming the reading for a missing
    file, a length other than its `num_points`, or a class outside 1..num_classes-1."""
    path = folder / f"{token}_lidarseg.bin"
    if not path.is_file():
        raise InputError(f"{path} does not exist: the submission has no predictions for lidar sample_data {token}")
    pred = np.fromfile(path, dtype=np.uint8)
    if len(pred) != num_points:
        raise InputError(f"{path}: {len(pred)} predictions for lidar sample_data {token}, which has {num_points} "
                         "points")
    bad = np.flatnonzero((pred == 0) | (pred >= num_classes))
    if len(bad):
        raise InputError(f"{path}: prediction {int(pred[bad[0]])} at point {int(bad[0])} of lidar sample_data "
                         f"{token} is outside 1..{num_classes - 1} ({len(bad)} such points; 0 is the ignore class, "
                         "never predicted)")
    return pred
