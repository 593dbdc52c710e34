"""The lidar segmentation evaluation job: the split's keyframe lidar readings, their ground-truth labels (through
the one `SensorReader`: `lidar_points/` or the label files) mapped to the challenge classes, the submission's
predictions checked and counted into the devkit's confusion matrix, and its result dict written as
`lidarseg_results.json` (with `confusion.parquet`, one row per ground-truth x predicted class).

```python
from nuparquet.evaluation.segmentation import evaluate_lidarseg
result = evaluate_lidarseg("OUT", "results/", "eval/", split="val")
result.metrics["miou"]
```
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import InputError
from nuparquet.evaluation.options import EvalOptions
from nuparquet.evaluation.segmentation.classes import COARSE_NAMES, NUM_CLASSES, fine_to_coarse_lookup
from nuparquet.evaluation.segmentation.confusion import frame_confusion, lidarseg_metrics
from nuparquet.evaluation.segmentation.submission import predictions_folder, read_meta, read_predictions
from nuparquet.options import resolve
from nuparquet.progress import OnProgress, Reporter

RESULTS_NAME = "lidarseg_results.json"
LIDAR_CHANNEL = "LIDAR_TOP"


@dataclass
class LidarsegResult:
    """What a lidar segmentation evaluation found and wrote.

    metrics: `LidarSegEval.evaluate`'s dict (also `summary`, the name every task's result has); confusion: (17, 17)
    int64 points of ground-truth class (row) predicted as class (column), ignore row and column zeroed; meta: the
    submission's meta; frames: the evaluated lidar sample_data tokens; out: the directory written (None: nothing
    written); notes: what a user should know."""

    metrics: dict
    confusion: np.ndarray
    meta: dict
    frames: list[str]
    out: Path | None = None
    notes: list[str] = field(default_factory=list)
    slices: None = None  # no slices for this task (the CLI asks every result)

    @property
    def summary(self) -> dict:
        return self.metrics


def split_frames(ds, split: str) -> tuple[pl.DataFrame, list[str]]:
    """The keyframe LIDAR_TOP readings (token, filename, scene_name) of the split's scenes in the dataset, in the
    devkit's order (the split's scene order, then by time), and notes (scenes of the split not in the dataset)."""
    from nuparquet.evaluation.splits import split_scene_names

    names = split_scene_names(split, dataroot=ds.dataroot, version=ds.version)
    order = pl.DataFrame({"scene_name": names, "_scene": range(len(names))},
                         schema={"scene_name": pl.String, "_scene": pl.Int64})
    frames = (ds.scan("frames")
              .filter((pl.col("channel") == LIDAR_CHANNEL) & pl.col("is_key_frame"))
              .select(pl.col("token").cast(pl.String), "filename", pl.col("scene_name").cast(pl.String),
                      "timestamp")
              .collect()
              .join(order, on="scene_name", how="inner")
              .sort("_scene", "timestamp"))
    found = frames["scene_name"].n_unique()
    notes = [] if found == len(names) else [f"the dataset holds {found} of the {len(names)} scenes of split {split}: "
                                            "evaluated on those"]
    return frames.select("token", "filename", "scene_name"), notes


def evaluate_lidarseg(dataset, results, out=None, options: EvalOptions | None = None, *,
                      on_progress: OnProgress | None = None, **fields) -> LidarsegResult:
    """Evaluate a lidar segmentation submission on a converted dataset exactly as nuscenes-devkit's LidarSegEval
    does (mIoU, frequency-weighted IoU and the IoU of each of the 16 challenge classes; index 0 ignored).

    `dataset`: a `Dataset` or the path of a converted output with lidarseg labels; `results`: the submission
    folder (`lidarseg/<split>/<token>_lidarseg.bin`, `<split>/submission.json`); `out`: the directory to write
    (None: nothing written). Settings as an `EvalOptions` (its task lidarseg) or as its keywords (`split=`,
    `overwrite=`; the others do not apply to this task).

    Raises:
        UsageError: bad settings (unknown split, an `out` that holds files), a dataset without lidarseg labels.
        InputError: a submission the devkit would refuse (a missing file, a wrong number of predictions, a class
            outside 1..16: the message names the lidar sample_data token), or labels it cannot map.
    """
    from nuparquet.dataset import as_dataset
    from nuparquet.errors import UsageError
    from nuparquet.evaluation.run import _check_out

    options = resolve(EvalOptions, options, {"task": "lidarseg", **fields})
    if options.by or options.config or options.config_file:
        raise UsageError("--by, --config and --config-file do not apply to --task lidarseg")
    ds = as_dataset(dataset)
    results = Path(results)
    out = Path(out) if out is not None else None
    if out is not None:
        _check_out(out, ds, options.overwrite)
    with Reporter(on_progress, "eval lidarseg", total=None, unit="frame") as rep:
        rep.note("read the submission")
        meta = read_meta(results, options.split)
        folder = predictions_folder(results, options.split)
        lookup = fine_to_coarse_lookup(ds)
        frames, notes = split_frames(ds, options.split)
        if frames.is_empty():
            raise InputError(f"split {options.split}: the dataset holds no keyframe {LIDAR_CHANNEL} reading of its "
                             "scenes (the devkit has no confusion matrix to score)")
        rep.set_total(frames.height)
        confusion = np.zeros((NUM_CLASSES, NUM_CLASSES), dtype=np.int64)
        for token, filename in frames.select("token", "filename").iter_rows():
            _, fine = ds.sensors.lidar(token, filename, labels="lidarseg")
            bad = np.flatnonzero((fine < 0) | (fine >= len(lookup)))
            if len(bad) == 0:
                bad = np.flatnonzero(lookup[fine] < 0)
            if len(bad):
                raise InputError(f"lidarseg label {int(fine[bad[0]])} at point {int(bad[0])} of lidar sample_data "
                                 f"{token} is the index of no category")
            pred = read_predictions(folder, token, len(fine), NUM_CLASSES)
            confusion += frame_confusion(lookup[fine], pred)
            rep.advance()
        result = LidarsegResult(metrics=lidarseg_metrics(confusion), confusion=confusion, meta=meta,
                                frames=frames["token"].to_list(), out=out, notes=notes)
        if out is not None:
            write(out, result)
    return result


def confusion_table(confusion: np.ndarray) -> pl.DataFrame:
    """One row per (ground-truth class, predicted class): gt_index, gt_class, pred_index, pred_class, points."""
    gt, pred = np.indices(confusion.shape)
    names = np.array(COARSE_NAMES, dtype=object)
    return pl.DataFrame({"gt_index": gt.ravel(), "gt_class": names[gt.ravel()].tolist(), "pred_index": pred.ravel(),
                         "pred_class": names[pred.ravel()].tolist(), "points": confusion.ravel()})


def write(out: Path, result: LidarsegResult) -> None:
    """`lidarseg_results.json` (the devkit's dict as its verbose printout dumps it: indent 4, key order kept, NaN
    written as NaN) and `confusion.parquet`, into `out` at once (`atomic_directory`)."""
    from nuparquet.atomic import atomic_directory

    with atomic_directory(out, overwrite=True, checked=True) as partial:
        (partial / RESULTS_NAME).write_text(json.dumps(result.metrics, indent=4, sort_keys=False))
        confusion_table(result.confusion).write_parquet(partial / "confusion.parquet")
