"""The panoptic evaluation job (tasks "panoptic" and "panoptic-tracking"): the split's keyframe lidar readings,
their Panoptic nuScenes ground truth (through the one `SensorReader`: `lidar_points/` or the label files) mapped to
the challenge classes, the submission's predictions checked, and per frame its segments counted into the devkit's
`PanopticEval` (and, for tracking, `PanopticTrackingEval`); written as the devkit's `<task>-result.json` with
`classes.parquet` (per class TP, FP, FN, IoU sums) and `instances.parquet` (per frame and instance its PQ term).

```python
from nuparquet.evaluation.panoptic import evaluate_panoptic
result = evaluate_panoptic("OUT", "results/", "eval/", split="val", task="panoptic-tracking")
result.metrics["tracking"]["all"]["PAT"], result.instances.filter(pl.col("term") == "FN")
```
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import InputError, UsageError
from nuparquet.evaluation.options import EvalOptions
from nuparquet.evaluation.panoptic.quality import TERMS, PanopticQuality, class_kind
from nuparquet.evaluation.panoptic.segments import frame_segments
from nuparquet.evaluation.panoptic.submission import (
    predictions_folder,
    read_meta,
    read_predictions,
)
from nuparquet.evaluation.panoptic.tracking import PanopticTracking
from nuparquet.evaluation.segmentation.classes import (
    COARSE_NAMES,
    NUM_CLASSES,
    fine_to_coarse_lookup,
)
from nuparquet.options import resolve
from nuparquet.progress import OnProgress, Reporter

DEVKIT_TASK = {"panoptic": "segmentation", "panoptic-tracking": "tracking"}  # our task -> the devkit's


@dataclass
class PanopticResult:
    """What a panoptic evaluation found and wrote.

    metrics: the dict `NuScenesPanopticEval.evaluate` writes ({"segmentation": ..., and for panoptic-tracking
    "tracking": ...}; also `summary`); classes: one row per class (TP, FP, FN, IoU sum of the segmentation
    evaluation; for tracking also its float32-summed TP IoUs and identity switches); instances: one row per
    ground-truth and predicted instance per frame with its PQ term (TP, FN, FP, or null: unmatched and under
    min_inst_points); meta: the submission's; frames: the evaluated lidar sample_data tokens; out: the directory
    written (None: nothing written); notes: what a user should know."""

    metrics: dict
    classes: pl.DataFrame
    instances: pl.DataFrame
    meta: dict
    frames: list[str]
    out: Path | None = None
    notes: list[str] = field(default_factory=list)
    slices: pl.DataFrame | None = None  # one row per (by, slice) (`slicing.SliceEvaluations.table`), None without by
    slice_summaries: dict = field(default_factory=dict)  # {(by, slice): the devkit's result dict of the slice}

    @property
    def summary(self) -> dict:
        return self.metrics


def evaluate_panoptic(dataset, results, out=None, options: EvalOptions | None = None, *,
                      on_progress: OnProgress | None = None, **fields) -> PanopticResult:
    """Evaluate a Panoptic nuScenes submission on a converted dataset exactly as nuscenes-devkit's
    NuScenesPanopticEval does: task "panoptic" its segmentation (PQ, SQ, RQ, mIoU, PQ-dagger), task
    "panoptic-tracking" its tracking as well (PAT, TQ, PTQ, sPTQ, LSTQ, S_assoc, MOTSA, sMOTSA, MOTSP, PTQ-dagger).

    `dataset`: a `Dataset` or the path of a converted output with panoptic labels; `results`: the submission
    folder (`panoptic/<split>/<token>_panoptic.npz`, `<split>/submission.json`); `out`: the directory to write
    (None: nothing written). Settings as an `EvalOptions` (task panoptic or panoptic-tracking) or as its keywords
    (`task=`, `split=`, `min_inst_points=` (the devkit's default 15), `overwrite=`).

    Raises:
        UsageError: bad settings (unknown split, an `out` that holds files, a submission.json of the other task),
            a dataset without panoptic labels.
        InputError: a submission the devkit would refuse or miscount (a missing file, a wrong number of labels, a
            class outside 0..16: the message names the file and the lidar sample_data token), labels it cannot
            map, or a tracking split without any thing instance (the devkit divides by zero).
    """
    from nuparquet.dataset import as_dataset
    from nuparquet.evaluation.run import _check_out
    from nuparquet.evaluation.segmentation.run import frame_scenes, split_frames
    from nuparquet.evaluation.slices import parse_bins

    options = resolve(EvalOptions, options, fields if options is not None else {"task": "panoptic", **fields})
    if options.task not in DEVKIT_TASK:
        raise UsageError(f"evaluate_panoptic evaluates --task panoptic or panoptic-tracking, not {options.task}")
    if options.config or options.config_file:
        raise UsageError(f"--config and --config-file do not apply to --task {options.task}")
    bins = parse_bins(options.bins) if options.bins else None
    if options.min_inst_points < 0:
        raise UsageError(f"--min-inst-points must be 0 or more, got {options.min_inst_points}")
    ds = as_dataset(dataset)
    if "tables/panoptic" not in ds.datasets:
        raise UsageError(f"{ds.root} has no panoptic labels (the dataroot had no panoptic.json when converted)")
    results, out = Path(results), (Path(out) if out is not None else None)
    if out is not None:
        _check_out(out, ds, options.overwrite)
    tracking = options.task == "panoptic-tracking"
    with Reporter(on_progress, f"eval {options.task}", total=None, unit="frame") as rep:
        rep.note("read the submission")
        meta = read_meta(results, options.split)
        if meta.get("task", DEVKIT_TASK[options.task]) != DEVKIT_TASK[options.task]:
            other = next(ours for ours, theirs in DEVKIT_TASK.items() if theirs == meta["task"])
            raise UsageError(f"{results / options.split / 'submission.json'} is a {meta['task']} submission: "
                             f"evaluate it with --task {other}")
        folder = predictions_folder(results, options.split)
        lookup = fine_to_coarse_lookup(ds)
        frames, notes = split_frames(ds, options.split)
        if frames.is_empty():
            raise InputError(f"split {options.split}: the dataset holds no keyframe LIDAR_TOP reading of its scenes")
        slices = None
        if options.by:
            from nuparquet.evaluation.panoptic.slicing import SliceEvaluations, check_by

            check_by(options.by, ds.scan("scenes").collect_schema().names(), options.task)
            slices = SliceEvaluations(options.by, frame_scenes(ds, frames, options.by), bins,
                                      options.min_inst_points, tracking)
        rep.set_total(frames.height)
        quality = PanopticQuality(options.min_inst_points)
        tracker = PanopticTracking(options.min_inst_points) if tracking else None
        instances = []
        for frame, (token, _, scene) in enumerate(frames.iter_rows()):
            gt = _ground_truth(ds, token, lookup)
            seg = frame_segments(gt, read_predictions(folder, token, len(gt), NUM_CLASSES), lookup)
            instances.append((token, seg, quality.add(seg)))
            if tracker is not None:
                tracker.add(scene, seg)
            if slices is not None:
                slices.add(frame, scene, seg)
            rep.advance()
        metrics = {"segmentation": quality.metrics()}
        if tracker is not None:
            metrics["tracking"] = tracker.metrics()
        result = PanopticResult(metrics=metrics, classes=class_table(quality, tracker),
                                instances=instance_table(instances), meta=meta, frames=frames["token"].to_list(),
                                out=out, notes=notes)
        if slices is not None:
            result.slice_summaries, slice_notes = slices.summaries()
            result.slices = slices.table(result.slice_summaries)
            result.notes += slice_notes
        if out is not None:
            write(out, result, DEVKIT_TASK[options.task], plots=options.plots)
    return result


def _ground_truth(ds, token: str, lookup: np.ndarray) -> np.ndarray:
    """(P,) int64 panoptic labels of lidar reading `token`; InputError for a category index no category has (the
    devkit's mapper raises KeyError there)."""
    gt = ds.sensors.labels(token, "panoptic")
    fine = gt // 1000
    bad = np.flatnonzero(fine >= len(lookup))
    if len(bad) == 0:
        bad = np.flatnonzero(lookup[fine] < 0)
    if len(bad):
        raise InputError(f"panoptic label {int(gt[bad[0]])} at point {int(bad[0])} of lidar sample_data {token}: "
                         f"category index {int(fine[bad[0]])} is the index of no category")
    return gt


def class_table(quality: PanopticQuality, tracker: PanopticTracking | None) -> pl.DataFrame:
    """One row per class: class_index, class, kind (thing, stuff, ignore), tp, fp, fn, iou_sum (the segmentation
    evaluation's counts); with tracking also tracking_tp/fp/fn, tracking_iou_sum (float32 IoUs summed), switches,
    soft_switches."""
    table = {"class_index": np.arange(NUM_CLASSES), "class": list(COARSE_NAMES),
             "kind": [class_kind(c) for c in range(NUM_CLASSES)], "tp": quality.tp, "fp": quality.fp,
             "fn": quality.fn, "iou_sum": quality.iou_sum}
    if tracker is not None:
        table.update({"tracking_tp": tracker.tp, "tracking_fp": tracker.fp, "tracking_fn": tracker.fn,
                      "tracking_iou_sum": tracker.iou_sum, "switches": tracker.switches,
                      "soft_switches": tracker.soft_switches})
    return pl.DataFrame(table)


def instance_table(frames: list) -> pl.DataFrame:
    """One row per instance per frame: sample_data_token, side (gt, pred), label (the raw panoptic label), class_index,
    class, points (its points outside the ignored ground truth), matched_label (the other side's label where they
    matched), iou, term (TP, FN, FP; null: unmatched and under min_inst_points). Built once from every frame's
    arrays."""
    columns: dict[str, list] = {name: [] for name in ("frame", "side", "label", "class_index", "points",
                                                      "matched_label", "iou", "term")}
    for frame, (_, seg, terms) in enumerate(frames):
        for side, ids, points, classes, other in (("gt", seg.gt_ids, seg.gt_points, seg.gt_class, seg.pred_ids),
                                                  ("pred", seg.pred_ids, seg.pred_points, seg.pred_class,
                                                   seg.gt_ids)):
            rows = terms[side]
            index, match = rows["index"], rows["match"]
            columns["frame"].append(np.full(len(index), frame))
            columns["side"].append(np.full(len(index), side == "gt"))
            columns["label"].append(ids[index] - 1)
            columns["class_index"].append(classes[index])
            columns["points"].append(points[index])
            columns["matched_label"].append(np.append(other - 1, -1)[match])  # -1: no match
            columns["iou"].append(rows["iou"])
            columns["term"].append(rows["term"])
    joined = {name: (np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)) for name, parts in columns.items()}
    tokens = np.array([token for token, _, _ in frames] or [""], dtype=object)
    names = np.array(COARSE_NAMES, dtype=object)
    table = pl.DataFrame({
        "sample_data_token": pl.Series(tokens[joined["frame"]].tolist(), dtype=pl.String),
        "side": pl.Series(np.where(joined["side"].astype(bool), "gt", "pred").tolist(), dtype=pl.String),
        "label": pl.Series(joined["label"], dtype=pl.Int64),
        "class_index": pl.Series(joined["class_index"], dtype=pl.Int64),
        "class": pl.Series(names[joined["class_index"].astype(np.int64)].tolist(), dtype=pl.String),
        "points": pl.Series(joined["points"], dtype=pl.Int64),
        "matched_label": pl.Series(joined["matched_label"], dtype=pl.Int64),
        "iou": pl.Series(joined["iou"], dtype=pl.Float64),
        "term": pl.Series(np.array(TERMS, dtype=object)[joined["term"].astype(np.int64)].tolist(), dtype=pl.String)})
    return table.with_columns(pl.when(pl.col("matched_label") >= 0).then(pl.col("matched_label"))
                              .alias("matched_label"))


def write(out: Path, result: PanopticResult, devkit_task: str, *, plots: bool = True) -> None:
    """`<segmentation|tracking>-result.json` (the devkit's `save_result`: indent 2, key order kept, NaN written as
    NaN), `classes.parquet`, `instances.parquet`, the slices' files and `plots/`, into `out` at once
    (`atomic_directory`)."""
    from nuparquet.atomic import atomic_directory

    from nuparquet.evaluation.run import slug

    with atomic_directory(out, overwrite=True, checked=True) as partial:
        (partial / f"{devkit_task}-result.json").write_text(json.dumps(result.metrics, indent=2))
        result.classes.write_parquet(partial / "classes.parquet")
        result.instances.write_parquet(partial / "instances.parquet")
        if result.slices is not None:
            result.slices.write_parquet(partial / "slices.parquet")
            for (by, label), metrics in result.slice_summaries.items():
                folder = partial / "slices" / slug(by) / slug(label)
                folder.mkdir(parents=True, exist_ok=True)
                (folder / f"{devkit_task}-result.json").write_text(json.dumps(metrics, indent=2))
        if plots:
            from nuparquet.evaluation.panoptic.plots import write_plots

            write_plots(partial / "plots", result.metrics)
