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

import polars as pl

from nuparquet.evaluation.tracking.config import resolve_tracking_config
from nuparquet.evaluation.tracking.inputs import evaluate_rows, prepare
from nuparquet.evaluation.options import EvalOptions
from nuparquet.options import resolve
from nuparquet.progress import OnProgress, Reporter

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


def evaluate_tracking(dataset, results, out=None, options: EvalOptions | None = None, *,
                      on_progress: OnProgress | None = None, **fields) -> TrackingResult:
    """Evaluate a tracking submission on a converted dataset, exactly as nuscenes-devkit's TrackingEval (with
    motmetrics 1.4.0) does.

    `dataset`: a `Dataset` or the path of a converted output; `results`: the submission (the devkit's tracking
    JSON); `out`: the directory to write (None: nothing written). Settings as an `EvalOptions` (its task tracking) or as its
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

    options = resolve(EvalOptions, options, {"task": "tracking", **fields})
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
