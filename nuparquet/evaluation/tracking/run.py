"""The tracking evaluation job: read the submission, load the ground truth, filter, build the tracks, score them
(overall and per slice), and write the devkit's files, the tracks as Parquet and the plots.

```python
from nuparquet.evaluation.tracking import evaluate_tracking
result = evaluate_tracking("OUT", "tracking_results.json", "eval/", split="val")
result.summary["amota"], result.tracks.filter(pl.col("switches") > 0)
```
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import InputError
from nuparquet.evaluation import filters
from nuparquet.evaluation.boxes import Boxes
from nuparquet.evaluation.classes import CATEGORY_TO_TRACKING, CYCLE_CLASSES
from nuparquet.evaluation.ground_truth import GroundTruth, load_ground_truth
from nuparquet.evaluation.splits import is_predefined
from nuparquet.evaluation.submission import (
    MAX_LISTED, TRACKING_FIELDS, SubmittedBoxes, check_samples, read_boxes, restricted_to_split,
)
from nuparquet.evaluation.tracking.config import TrackingConfig, resolve_tracking_config
from nuparquet.evaluation.tracking.options import TrackingOptions
from nuparquet.evaluation.tracking.scoring import TrackingEvaluation, score_tracks
from nuparquet.evaluation.tracking.tracks import Timeline, TrackedBoxes, build_tracks
from nuparquet.geometry.cuboids import Cuboids
from nuparquet.options import resolve
from nuparquet.progress import OnProgress, Reporter

SUMMARY_NAME = "metrics_summary.json"
DETAILS_NAME = "metrics_details.json"


@dataclass
class TrackingResult:
    """What a tracking evaluation found and wrote.

    summary, details: metrics_summary.json / metrics_details.json (the devkit's keys and values); tracks: one row
    per ground-truth track of an evaluated class (`tables.ground_truth_tracks`); predicted_tracks: one row per
    predicted track; slices: one row per (by, slice) (None without `by`); slice_summaries, slice_details:
    {(by, slice): ...}; out: the directory written (None: nothing written); notes: what a user should know."""

    summary: dict
    details: dict
    tracks: pl.DataFrame
    predicted_tracks: pl.DataFrame
    slices: pl.DataFrame | None = None
    slice_summaries: dict = field(default_factory=dict)
    slice_details: dict = field(default_factory=dict)
    out: Path | None = None
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Inputs:
    """The filtered boxes of one evaluation, before tracking: rows of the ground truth and of the submission
    that pass the devkit's filters, and everything needed to make tracks of them."""

    gt: GroundTruth
    sub: SubmittedBoxes
    timeline: Timeline
    gt_kept: np.ndarray
    pred_kept: np.ndarray
    pred_sample: np.ndarray
    pred_class: np.ndarray
    gt_distance_m: np.ndarray
    pred_distance_m: np.ndarray
    gt_reason: np.ndarray
    pred_reason: np.ndarray


def check_track_ids(sub: SubmittedBoxes, path) -> None:
    """A tracking_id given to two boxes of one sample is refused (the devkit would match one of them by list
    position and give both its track's score), naming the sample and the boxes."""
    ids = sub.labels["tracking_id"]
    if not len(ids):
        return
    _, code = np.unique(ids.astype(str), return_inverse=True)
    key = sub.box_sample * (int(code.max()) + 1) + code.reshape(-1)
    order = np.argsort(key, kind="stable")
    repeated = order[1:][key[order][1:] == key[order][:-1]]
    if len(repeated):
        first = {int(k): int(r) for k, r in zip(key[order][::-1], order[::-1])}
        lines = [f"sample {sub.sample_tokens[sub.box_sample[r]]} box {int(sub.box_index[r])}: tracking_id "
                 f"{ids[r]!r} already given to box {int(sub.box_index[first[int(key[r])]])} of the sample"
                 for r in repeated[:MAX_LISTED]]
        more = f"\n  ... and {len(repeated) - MAX_LISTED} more" if len(repeated) > MAX_LISTED else ""
        raise InputError(f"{path}: {len(repeated)} problem(s) in the submission:\n  " + "\n  ".join(lines) + more)


def prepare(ds, results, config: TrackingConfig, split: str, *, annotation_columns=(), scene_columns=()) -> Inputs:
    """Read and check the submission, load the ground truth of `split`, apply the devkit's filters."""
    sub = read_boxes(results, TRACKING_FIELDS, max_boxes_per_sample=config.max_boxes_per_sample,
                     class_names=config.tracking_names)
    check_track_ids(sub, results)
    names = config.class_names
    gt = load_ground_truth(ds, split, names, annotation_columns=["instance_token", *annotation_columns],
                           scene_columns=scene_columns, category_map=CATEGORY_TO_TRACKING, one_attribute=False)
    custom = not is_predefined(split)
    check_samples(sub, gt.samples.token.tolist(), split=split, path=results, allow_extra=custom)
    if custom:
        sub = restricted_to_split(sub, gt.samples.token)
    sample_of = {token: i for i, token in enumerate(gt.samples.token.tolist())}
    sample_index = np.array([sample_of[t] for t in sub.sample_tokens.tolist()], dtype=np.int64)
    pred_sample = sample_index[sub.box_sample] if len(sub) else np.zeros(0, np.int64)
    class_of = {name: i for i, name in enumerate(names)}
    class_names, inverse = np.unique(sub.class_name.astype(str), return_inverse=True)
    pred_class = (np.array([class_of[n] for n in class_names.tolist()], np.int64)[inverse.reshape(-1)]
                  if len(sub) else np.zeros(0, np.int64))
    n = len(sub)
    pred = Boxes(sample_index=pred_sample, class_index=pred_class, translation_m=sub.translation_m,
                 size_wlh_m=sub.size_wlh_m, rotation_wxyz=sub.rotation_wxyz, velocity_mps=sub.velocity_mps,
                 attribute=np.full(n, "", object), score=sub.score, num_pts=sub.num_pts)
    class_range = np.array([float(config.class_range[name]) for name in names])
    cycle = np.isin(np.array(names), CYCLE_CLASSES)
    gt_distance = filters.ego_distances_m(gt.boxes, gt.samples.ego_xyz_m)
    pred_distance = filters.ego_distances_m(pred, gt.samples.ego_xyz_m)
    gt_reason = filters.filter_reasons(gt.boxes, gt_distance, class_range, cycle, gt.racks)
    pred_reason = filters.filter_reasons(pred, pred_distance, class_range, cycle, gt.racks)
    scene_of = {token: i for i, token in enumerate(gt.scenes["token"].to_list())}
    scene_index = np.array([scene_of[t] for t in gt.samples.scene_token.tolist()], dtype=np.int64)
    timeline = Timeline.of(scene_index, gt.samples.timestamp_us, gt.scenes.height)
    return Inputs(gt=gt, sub=sub, timeline=timeline, gt_kept=np.flatnonzero(gt_reason == filters.KEPT),
                  pred_kept=np.flatnonzero(pred_reason == filters.KEPT), pred_sample=pred_sample,
                  pred_class=pred_class, gt_distance_m=gt_distance, pred_distance_m=pred_distance,
                  gt_reason=gt_reason, pred_reason=pred_reason)


def tracks_of(inputs: Inputs, gt_rows: np.ndarray, pred_rows: np.ndarray) -> tuple[TrackedBoxes, TrackedBoxes]:
    """The tracks (interpolated) of the given rows of the ground truth and the submission (kept rows, in order)."""
    gt, sub = inputs.gt, inputs.sub
    boxes = gt.boxes
    gt_tracks = build_tracks(
        Cuboids(boxes.translation_m[gt_rows], boxes.size_wlh_m[gt_rows], boxes.rotation_wxyz[gt_rows]),
        boxes.sample_index[gt_rows], gt.annotations["instance_token"].to_numpy().astype(object)[gt_rows],
        boxes.class_index[gt_rows], np.full(len(gt_rows), -1.0), inputs.timeline, average_scores=False)
    pred_tracks = build_tracks(
        Cuboids(sub.translation_m[pred_rows], sub.size_wlh_m[pred_rows], sub.rotation_wxyz[pred_rows]),
        inputs.pred_sample[pred_rows], sub.labels["tracking_id"][pred_rows], inputs.pred_class[pred_rows],
        sub.score[pred_rows], inputs.timeline, average_scores=True)
    return gt_tracks, pred_tracks


def evaluate_rows(inputs: Inputs, gt_rows: np.ndarray, pred_rows: np.ndarray, config: TrackingConfig
                  ) -> tuple[TrackingEvaluation, TrackedBoxes, TrackedBoxes]:
    gt_tracks, pred_tracks = tracks_of(inputs, gt_rows, pred_rows)
    evaluation = score_tracks(gt_tracks, pred_tracks, config, len(inputs.gt.samples), inputs.timeline.max_positions)
    return evaluation, gt_tracks, pred_tracks


def evaluate_tracking(dataset, results, out=None, options: TrackingOptions | None = None, *,
                      on_progress: OnProgress | None = None, **fields) -> TrackingResult:
    """Evaluate a tracking submission on a converted dataset, exactly as nuscenes-devkit's TrackingEval (with
    motmetrics 1.4.0) does.

    `dataset`: a `Dataset` or the path of a converted output; `results`: the submission (the devkit's tracking
    JSON); `out`: the directory to write (None: nothing written). Settings as a `TrackingOptions` or as its
    keywords (`split=`, `config=`, `config_file=`, `by=`, `bins=`, `plots=`, `overwrite=`).

    Raises:
        UsageError: bad settings (unknown split, configuration or slice; an `out` that holds files).
        InputError: a submission the devkit would refuse or mis-evaluate (the message names the sample and the
            box), or ground truth it cannot evaluate.
    """
    from nuparquet.dataset import as_dataset
    from nuparquet.evaluation.run import _check_out, _notes
    from nuparquet.evaluation.slices import needed_columns, parse_bins
    from nuparquet.evaluation.tracking import tables

    options = resolve(TrackingOptions, options, fields)
    config = resolve_tracking_config(options.config, options.config_file)
    bins = parse_bins(options.bins) if options.bins else None
    by = tuple(dict.fromkeys(options.by))
    ds = as_dataset(dataset)
    out = Path(out) if out is not None else None
    if out is not None:
        _check_out(out, ds, options.overwrite)
    steps = 5 + (1 if out is not None and options.plots else 0)
    with Reporter(on_progress, "eval tracking", total=None if by else steps, unit="step") as rep:
        rep.note("read the submission and the ground truth")
        annotation_names = ds.scan("annotations").collect_schema().names()
        scene_names = ds.scan("scenes").collect_schema().names()
        slice_annotation_columns, slice_scene_columns = needed_columns(by, annotation_names, scene_names)
        annotation_columns = list(dict.fromkeys(
            [*(["visibility_name"] if "visibility_name" in annotation_names else []), *slice_annotation_columns]))
        inputs = prepare(ds, results, config, options.split, annotation_columns=annotation_columns,
                         scene_columns=slice_scene_columns)
        rep.advance(step="tracks and metrics")
        whole, gt_tracks, pred_tracks = evaluate_rows(inputs, inputs.gt_kept, inputs.pred_kept, config)
        summary, details = whole.summary(config, inputs.sub.meta), whole.details()
        rep.advance(step="tables")
        gt_table = tables.ground_truth_tracks(inputs, whole, gt_tracks, pred_tracks, config)
        pred_table = tables.predicted_tracks(inputs, whole, gt_tracks, pred_tracks, config)
        rep.advance(step="slices" if by else "")
        slices, slice_summaries, slice_details = None, {}, {}
        if by:
            from nuparquet.evaluation.tracking.slicing import evaluate_slices

            slices, slice_summaries, slice_details = evaluate_slices(
                by, inputs, whole, gt_tracks, pred_tracks, config, bins, rep, steps)
        result = TrackingResult(summary=summary, details=details, tracks=gt_table, predicted_tracks=pred_table,
                                slices=slices, slice_summaries=slice_summaries, slice_details=slice_details,
                                out=out, notes=_notes(inputs.gt))
        rep.advance(step="write" if out is not None else "")
        if out is not None:
            from nuparquet.evaluation.tracking.output import write_result

            write_result(out, result, whole, config, plots=options.plots, reporter=rep)
    return result
