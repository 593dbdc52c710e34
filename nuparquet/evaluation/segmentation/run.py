"""The lidar segmentation evaluation job: the split's keyframe lidar readings, their ground-truth labels (through
the one `SensorReader`: `lidar_points/` or the label files) mapped to the challenge classes, the submission's
predictions checked and counted into the devkit's confusion matrix, and its result dict written as
`lidarseg_results.json` (with `confusion.parquet`, one row per ground-truth x predicted class, `plots/*.png`, and
with `by` the same per slice: `slices.parquet`, `slices/<by>/<slice>/lidarseg_results.json`).

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
    slices: pl.DataFrame | None = None  # one row per (by, slice) (`slicing.SliceConfusions.table`), None without by
    slice_summaries: dict = field(default_factory=dict)  # {(by, slice): the devkit's result dict of the slice}
    slice_confusions: dict = field(default_factory=dict)  # {(by, slice): (17, 17) int64}

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


def frame_scenes(ds, frames: pl.DataFrame, by) -> pl.DataFrame:
    """One row per frame of `frames`, in order: its scene's row of the `scenes` dataset (the slices' labels)."""
    from nuparquet.evaluation.segmentation.slicing import check_by

    scene_columns = ds.scan("scenes").collect_schema().names()
    check_by(by, scene_columns)
    wanted = list(dict.fromkeys(["name", "description", "log_location",
                                 *(b for b in by if b in scene_columns)]))
    scenes = ds.scan("scenes").select([pl.col(c).cast(pl.String) if c in ("name", "log_location") else pl.col(c)
                                       for c in wanted]).collect()
    return frames.select("scene_name").join(scenes, left_on="scene_name", right_on="name", how="left",
                                            maintain_order="left").rename({"scene_name": "name"})


def evaluate_lidarseg(dataset, results, out=None, options: EvalOptions | None = None, *,
                      on_progress: OnProgress | None = None, **fields) -> LidarsegResult:
    """Evaluate a lidar segmentation submission on a converted dataset exactly as nuscenes-devkit's LidarSegEval
    does (mIoU, frequency-weighted IoU and the IoU of each of the 16 challenge classes; index 0 ignored).

    `dataset`: a `Dataset` or the path of a converted output with lidarseg labels; `results`: the submission
    folder (`lidarseg/<split>/<token>_lidarseg.bin`, `<split>/submission.json`); `out`: the directory to write
    (None: nothing written). Settings as an `EvalOptions` (its task lidarseg) or as its keywords (`split=`,
    `by=` (distance, location, night, rain, scene or a scenes column: `slicing`), `bins=`, `plots=`,
    `overwrite=`; `config` does not apply to this task).

    Raises:
        UsageError: bad settings (unknown split, an `out` that holds files), a dataset without lidarseg labels.
        InputError: a submission the devkit would refuse (a missing file, a wrong number of predictions, a class
            outside 1..16: the message names the lidar sample_data token), or labels it cannot map.
    """
    from nuparquet.dataset import as_dataset
    from nuparquet.errors import UsageError
    from nuparquet.evaluation.run import _check_out

    from nuparquet.evaluation.segmentation.slicing import SliceConfusions
    from nuparquet.evaluation.slices import parse_bins

    options = resolve(EvalOptions, options, {"task": "lidarseg", **fields})
    if options.config or options.config_file:
        raise UsageError("--config and --config-file do not apply to --task lidarseg")
    bins = parse_bins(options.bins) if options.bins else None
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
        slices = SliceConfusions(options.by, frame_scenes(ds, frames, options.by), bins) if options.by else None
        rep.set_total(frames.height)
        confusion = np.zeros((NUM_CLASSES, NUM_CLASSES), dtype=np.int64)
        for frame, (token, filename, _) in enumerate(frames.iter_rows()):
            points, fine = ds.sensors.lidar(token, filename, labels="lidarseg")
            bad = np.flatnonzero((fine < 0) | (fine >= len(lookup)))
            if len(bad) == 0:
                bad = np.flatnonzero(lookup[fine] < 0)
            if len(bad):
                raise InputError(f"lidarseg label {int(fine[bad[0]])} at point {int(bad[0])} of lidar sample_data "
                                 f"{token} is the index of no category")
            pred = read_predictions(folder, token, len(fine), NUM_CLASSES)
            coarse = lookup[fine]
            counted = frame_confusion(coarse, pred)
            confusion += counted
            if slices is not None:
                slices.add(frame, points[:, :2], coarse, pred, counted)
            rep.advance()
        result = LidarsegResult(metrics=lidarseg_metrics(confusion), confusion=confusion, meta=meta,
                                frames=frames["token"].to_list(), out=out, notes=notes)
        if slices is not None:
            result.slice_summaries = slices.summaries()
            result.slices = slices.table(result.slice_summaries)
            result.slice_confusions = {key: slices.confusion[key] for key in result.slice_summaries}
        if out is not None:
            write(out, result, plots=options.plots)
    return result


def confusion_table(confusion: np.ndarray) -> pl.DataFrame:
    """One row per (ground-truth class, predicted class): gt_index, gt_class, pred_index, pred_class, points."""
    gt, pred = np.indices(confusion.shape)
    names = np.array(COARSE_NAMES, dtype=object)
    return pl.DataFrame({"gt_index": gt.ravel(), "gt_class": names[gt.ravel()].tolist(), "pred_index": pred.ravel(),
                         "pred_class": names[pred.ravel()].tolist(), "points": confusion.ravel()})


def write(out: Path, result: LidarsegResult, *, plots: bool = True) -> None:
    """`lidarseg_results.json` (the devkit's dict as its verbose printout dumps it: indent 4, key order kept, NaN
    written as NaN), `confusion.parquet`, `plots/` and the slices' files, into `out` at once
    (`atomic_directory`)."""
    from nuparquet.atomic import atomic_directory
    from nuparquet.evaluation.run import slug

    with atomic_directory(out, overwrite=True, checked=True) as partial:
        (partial / RESULTS_NAME).write_text(json.dumps(result.metrics, indent=4, sort_keys=False))
        confusion_table(result.confusion).write_parquet(partial / "confusion.parquet")
        if result.slices is not None:
            result.slices.write_parquet(partial / "slices.parquet")
            for (by, label), metrics in result.slice_summaries.items():
                folder = partial / "slices" / slug(by) / slug(label)
                folder.mkdir(parents=True, exist_ok=True)
                (folder / RESULTS_NAME).write_text(json.dumps(metrics, indent=4, sort_keys=False))
                confusion_table(result.slice_confusions[(by, label)]).write_parquet(folder / "confusion.parquet")
        if plots:
            from nuparquet.evaluation.segmentation.plots import write_plots

            write_plots(partial / "plots", result.metrics, result.confusion)
