"""The evaluation job: read the submission, load the ground truth, filter, match, compute the metrics (overall
and per slice), and write them.

```python
from nuparquet.evaluation import evaluate
result = evaluate("OUT", results="results.json", split="val", out="eval/", by=("distance",))
result.summary["nd_score"], result.predictions.filter(pl.col("matched_gt_2m").is_null())
```

Longer than our ~300-line norm on purpose: the whole pipeline of one evaluation (ground truth, filters, matching,
metrics, slices, outputs) reads top to bottom here; each step's work is in its own module.
"""

from __future__ import annotations

import json
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import UsageError
from nuparquet.evaluation import filters
from nuparquet.evaluation.boxes import Boxes
from nuparquet.evaluation.classes import CYCLE_CLASSES, MEAN_TP_NAMES, TP_METRICS
from nuparquet.evaluation.config import FAMILY_CONFIGS, DetectionConfig, resolve_config
from nuparquet.evaluation.ground_truth import GroundTruth, load_ground_truth
from nuparquet.evaluation.matching import Matches, match_boxes
from nuparquet.evaluation.metrics import (
    DetectionMetrics, MetricData, detection_metrics, match_errors, metric_data, serialize_details,
)
from nuparquet.evaluation.options import EvalOptions
from nuparquet.evaluation.tags import tag_evaluations, tagged_details, tagged_summary
from nuparquet.evaluation.tasks import task_function
from nuparquet.options import resolve
from nuparquet.evaluation.slices import dimension, needed_columns, parse_bins
from nuparquet.evaluation.splits import is_predefined
from nuparquet.evaluation.submission import SubmittedBoxes, check_samples, read_submission, restricted_to_split
from nuparquet.evaluation.tables import ground_truth_table, predictions_table
from nuparquet.progress import OnProgress, Reporter

SUMMARY_NAME = "metrics_summary.json"
DETAILS_NAME = "metrics_details.json"


@dataclass(frozen=True)
class Evaluation:
    """One evaluation of (already filtered) boxes: the devkit's `DetectionMetrics` and `DetectionMetricDataList`,
    and the matches they came from."""

    metrics: DetectionMetrics
    data: dict[tuple, MetricData]
    matches: Matches
    num_gt: int
    num_predictions: int

    def summary(self, meta: dict) -> dict:
        """metrics_summary.json: the devkit's keys, in its order, with the submission's meta. TruckScenes'
        (`Taxonomy.tagged_output`): its `DetectionMetricsList` of the tag "all" (whose own eval_time stays None),
        then the evaluation time and the meta."""
        if self.metrics.config.taxonomy.tagged_output:
            return tagged_summary({"all": self}, meta)
        return {**self.metrics.serialize(), "meta": dict(meta)}

    def details(self) -> dict:
        """metrics_details.json."""
        if self.metrics.config.taxonomy.tagged_output:
            return tagged_details({"all": self})
        return serialize_details(self.data)


def evaluate_boxes(gt: Boxes, pred: Boxes, config: DetectionConfig) -> Evaluation:
    """Match and score filtered boxes (class_index into `config.class_names`): the devkit's `evaluate()`.
    The evaluation time (matching and metrics, what the devkit's eval_time measures) goes into the metrics."""
    start = time.perf_counter()
    matches = match_boxes(gt, pred, config.dist_ths, len(config.class_names))
    data = metric_data(gt, pred, matches, config)
    metrics = detection_metrics(data, config)
    metrics = DetectionMetrics(metrics.config, metrics.label_aps, metrics.label_tp_errors, time.perf_counter() - start)
    return Evaluation(metrics, data, matches, len(gt), len(pred))


@dataclass
class EvalResult:
    """What an evaluation found and wrote.

    summary, details: the contents of metrics_summary.json / metrics_details.json (TruckScenes': the figures
    under summary["all"]); metrics: the `DetectionMetrics` behind them (`metrics.serialize()`: the figures, in
    either case); predictions, ground_truth: the tables of `nuparquet.evaluation.tables`;
    slices: one row per (by, slice) with its counts and headline metrics (None without --by); slice_summaries,
    slice_details: {(by, slice): metrics_summary / metrics_details}; out: the directory written (None: nothing
    written); notes: what a user should know (a split only partly present in the dataset, ...).
    """

    summary: dict
    details: dict
    metrics: DetectionMetrics
    predictions: pl.DataFrame
    ground_truth: pl.DataFrame
    slices: pl.DataFrame | None = None
    slice_summaries: dict = field(default_factory=dict)
    slice_details: dict = field(default_factory=dict)
    out: Path | None = None
    notes: list[str] = field(default_factory=list)


def _prediction_boxes(sub: SubmittedBoxes, sample_of: dict, class_names: tuple[str, ...]) -> tuple[Boxes, np.ndarray]:
    """The submission as Boxes (sample_index into the evaluated samples), and (N,) sample index per box."""
    sample_index = np.array([sample_of[t] for t in sub.sample_tokens.tolist()], dtype=np.int64)
    class_of = {name: i for i, name in enumerate(class_names)}
    box_sample = sample_index[sub.box_sample] if len(sub) else np.zeros(0, np.int64)
    names, inverse = np.unique(sub.detection_name.astype(str), return_inverse=True)
    class_index = np.array([class_of[name] for name in names.tolist()], dtype=np.int64)[inverse.reshape(-1)] \
        if len(sub) else np.zeros(0, np.int64)
    boxes = Boxes(cuboids=sub.cuboids, sample_index=box_sample, class_index=class_index,
                  velocity_mps=sub.velocity_mps, attribute=sub.attribute_name, score=sub.detection_score, num_pts=sub.num_pts)
    return boxes, box_sample


def _check_out(out: Path, dataset, overwrite: bool) -> None:
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file; give a directory")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise UsageError(f"--out {out} already holds files; pass --overwrite to replace it")
    if not dataset.is_remote:
        from nuparquet.atomic import check_apart

        check_apart(out, dataset.root, what="the converted dataset")


def evaluate(dataset, results, out=None, options: EvalOptions | None = None, *,
             on_progress: OnProgress | None = None, **fields) -> EvalResult:
    """Evaluate the submission `results` on `dataset` (a `Dataset` or the path of a converted output) exactly as
    nuscenes-devkit evaluates its benchmark (`task`: detection, DetectionEval, here; the others in their packages,
    `evaluation.tasks`), writing the metrics, plots and tables into the folder `out` (None: nothing written).

    Settings as an `EvalOptions` or as its keywords (``split=``, ``config=``, ``config_file=``, ``by=``, ``bins=``,
    ``plots=``, ``overwrite=``), or both (`nuparquet.options.resolve`). Progress goes to `on_progress` (one "step"
    per stage, one per slice).

    Raises:
        UsageError: bad settings (unknown split, configuration or slice, an --out that holds files).
        InputError: a submission the devkit would refuse (the message names the sample and the box), or ground
            truth it cannot evaluate.
    """
    from nuparquet.dataset import as_dataset

    options = resolve(EvalOptions, options, fields)
    if options.min_inst_points != EvalOptions.min_inst_points and not options.task.startswith("panoptic"):
        raise UsageError(f"--min-inst-points applies to --task panoptic and panoptic-tracking, not {options.task}")
    if options.tags and options.task != "detection":
        raise UsageError(f"--tags applies to --task detection (TruckScenes' per-tag metrics), not {options.task}")
    if options.task != "detection":  # the other benchmarks, each in its own package, through the one verb
        return task_function(options.task)(dataset, results, out, options, on_progress=on_progress)
    ds = as_dataset(dataset)
    config = resolve_config(options.config, options.config_file, default=FAMILY_CONFIGS.get(ds.source_format))
    taxonomy = config.taxonomy
    if taxonomy.family != _family(ds.source_format):
        raise UsageError(f"the configuration evaluates {taxonomy.family}'s detection classes "
                         f"({', '.join(taxonomy.detection_names[:4])}, ...), but {ds.root} is a {ds.source_format} "
                         f"dataset; use its own (--config {FAMILY_CONFIGS.get(ds.source_format, '?')}) or a "
                         "configuration file with its classes")
    if options.tags and not taxonomy.scene_tags:
        raise UsageError(f"--tags: the {taxonomy.family} benchmark has no scene tags (MAN TruckScenes' has: its "
                         "scenes' descriptions list them)")
    bins = parse_bins(options.bins) if options.bins else None
    by = tuple(dict.fromkeys(options.by))
    out = Path(out) if out is not None else None
    if out is not None:
        _check_out(out, ds, options.overwrite)
    steps = 6 + (1 if out is not None and options.plots else 0)
    # with slices the total is known once their labels are (each is a step): a bar's total never changes
    with Reporter(on_progress, "eval", total=None if by else steps, unit="step") as rep:
        rep.note("read the submission")
        sub = read_submission(results, max_boxes_per_sample=config.max_boxes_per_sample,
                              class_names=config.class_names, attribute_names=taxonomy.attribute_names)
        rep.advance(step="load the ground truth")
        annotation_names = ds.scan("annotations").collect_schema().names()
        scene_names = ds.scan("scenes").collect_schema().names()
        slice_annotation_columns, slice_scene_columns = needed_columns(by, annotation_names, scene_names)
        annotation_columns = list(dict.fromkeys(
            [*(["visibility_name"] if "visibility_name" in annotation_names else []), *slice_annotation_columns]))
        gt = load_ground_truth(ds, options.split, config.class_names, annotation_columns=annotation_columns,
                               scene_columns=slice_scene_columns, category_map=taxonomy.category_to_detection,
                               reference_channel=taxonomy.reference_channel)
        # a predefined split wants exactly its samples; a custom one ignores the others (devkit
        # load_prediction_of_sample_tokens) and takes the split's samples in its order
        custom = not is_predefined(options.split)
        check_samples(sub, gt.samples.token.tolist(), split=options.split, path=results, allow_extra=custom)
        if custom:
            sub = restricted_to_split(sub, gt.samples.token)
        rep.advance(step="filter")
        sample_of = {token: i for i, token in enumerate(gt.samples.token.tolist())}
        pred, pred_sample = _prediction_boxes(sub, sample_of, config.class_names)
        class_range = np.array([float(config.class_range[name]) for name in config.class_names])
        cycle = np.isin(np.array(config.class_names), CYCLE_CLASSES)
        gt_distance = filters.ego_distances_m(gt.boxes, gt.samples.ego_xyz_m)
        pred_distance = filters.ego_distances_m(pred, gt.samples.ego_xyz_m)
        gt_reason = filters.filter_reasons(gt.boxes, gt_distance, class_range, cycle, gt.racks)
        pred_reason = filters.filter_reasons(pred, pred_distance, class_range, cycle, gt.racks)
        gt_kept = np.flatnonzero(gt_reason == filters.KEPT)
        pred_kept = np.flatnonzero(pred_reason == filters.KEPT)
        gt_boxes, pred_boxes = gt.boxes.take(gt_kept), pred.take(pred_kept)
        rep.advance(step="match and score")
        whole = evaluate_boxes(gt_boxes, pred_boxes, config)
        rep.advance(step="tables")
        tp_index = list(config.dist_ths).index(config.dist_th_tp)
        tp_match = whole.matches.gt[tp_index]
        hit = np.flatnonzero(tp_match >= 0)
        errors = match_errors(gt_boxes, pred_boxes, tp_match[hit], hit, whole.matches.distance_m[tp_index, hit],
                              config.class_names, taxonomy)
        errors_at_tp = {}
        for metric in TP_METRICS:
            values = np.full(len(pred_boxes), np.nan)
            values[hit] = errors[metric]
            errors_at_tp[metric] = values
        predictions = predictions_table(sub, pred_sample, gt.samples, pred_distance, pred_reason, pred_kept,
                                        pred_boxes.class_index, whole.matches, errors_at_tp, tp_index,
                                        gt.annotations["token"].to_numpy().astype(object)[gt_kept])
        ground_truth = ground_truth_table(gt, gt_distance, gt_reason, gt_kept, whole.matches,
                                          sub.box_index[pred_kept])
        rep.advance(step="slices" if by else "")
        slices, slice_summaries, slice_details = None, {}, {}
        if by:
            slices, slice_summaries, slice_details = _evaluate_slices(
                by, gt, gt_kept, gt_boxes, pred_boxes, gt_distance[gt_kept], pred_distance[pred_kept], tp_match,
                config, bins, sub.meta, rep, steps)
        summary, details = whole.summary(sub.meta), whole.details()
        if options.tags:
            description = dict(zip(gt.scenes["token"].to_list(), gt.scenes["description"].to_list()))
            evaluations = {"all": whole, **tag_evaluations(
                gt_boxes, pred_boxes, [description[t] for t in gt.samples.scene_token.tolist()], config,
                evaluate_boxes)}
            summary, details = tagged_summary(evaluations, sub.meta), tagged_details(evaluations)
        notes = _notes(gt)
        result = EvalResult(summary=summary, details=details, metrics=whole.metrics, predictions=predictions,
                            ground_truth=ground_truth, slices=slices, slice_summaries=slice_summaries,
                            slice_details=slice_details, out=out, notes=notes)
        rep.advance(step="write" if out is not None else "")
        if out is not None:
            _write(out, result, whole, config, plots=options.plots, reporter=rep)
    return result


def _family(source_format: str) -> str:
    """The detection vocabulary a source format's datasets are labelled in (Lyft and T4 convert as nuScenes)."""
    return source_format if source_format in FAMILY_CONFIGS else "nuscenes"


def _notes(gt: GroundTruth) -> list[str]:
    found = gt.scenes.height
    if found < gt.split_scenes:
        return [f"split {gt.split} lists {gt.split_scenes} scenes; {found} of them are in this dataset and were "
                "evaluated"]
    return []


def _evaluate_slices(by, gt: GroundTruth, gt_kept, gt_boxes: Boxes, pred_boxes: Boxes, gt_distance, pred_distance,
                     tp_match, config, bins, meta, reporter, steps: int) -> tuple[pl.DataFrame, dict, dict]:
    sample_scene = (pl.DataFrame({"sample_token": gt.samples.token, "scene_token": gt.samples.scene_token,
                                  "scene_name": gt.samples.scene_name, "timestamp": gt.samples.timestamp_us},
                                 schema={"sample_token": pl.String, "scene_token": pl.String,
                                         "scene_name": pl.String, "timestamp": pl.Int64})
                    .join(gt.scenes, left_on="scene_token", right_on="token", how="left", maintain_order="left"))
    dimensions = [dimension(name, gt_ego_distance_m=gt_distance, pred_ego_distance_m=pred_distance,
                            gt_annotations=gt.annotations[gt_kept], gt_attribute=gt_boxes.attribute,
                            pred_attribute=pred_boxes.attribute, gt_sample=gt_boxes.sample_index,
                            pred_sample=pred_boxes.sample_index, sample_scene=sample_scene, pred_matched_gt=tp_match,
                            bins=bins) for name in by]
    reporter.set_total(steps + sum(len(d.labels) for d in dimensions))
    rows, summaries, details = [], {}, {}
    for dim in dimensions:
        for label in dim.labels:
            gt_mask, pred_mask = dim.masks(label)
            evaluation = evaluate_boxes(gt_boxes.take(gt_mask), pred_boxes.take(pred_mask), config)
            summaries[(dim.name, label)] = evaluation.summary(meta)
            details[(dim.name, label)] = evaluation.details()
            summary = evaluation.metrics.serialize()
            rows.append({"by": dim.name, "slice": label, "num_gt": evaluation.num_gt,
                         "num_predictions": evaluation.num_predictions, "mAP": summary["mean_ap"],
                         "NDS": summary["nd_score"], **{MEAN_TP_NAMES[m]: summary["tp_errors"][m] for m in TP_METRICS},
                         **{f"AP_{name}": float(summary["mean_dist_aps"][name]) for name in config.class_names}})
            reporter.advance(step=f"slice {dim.name} {label}")
    schema = {"by": pl.String, "slice": pl.String, "num_gt": pl.Int64, "num_predictions": pl.Int64, "mAP": pl.Float64,
              "NDS": pl.Float64, **{MEAN_TP_NAMES[m]: pl.Float64 for m in TP_METRICS},
              **{f"AP_{name}": pl.Float64 for name in config.class_names}}
    return pl.DataFrame(rows, schema=schema), summaries, details


def slug(label: str) -> str:
    """A slice label as a folder name."""
    return re.sub(r"[^A-Za-z0-9._+-]+", "_", label).strip("._") or "_"


def _write_json(path: Path, content: dict) -> None:
    with open(path, "w") as f:
        json.dump(content, f, indent=2)


def _write(out: Path, result: EvalResult, whole: Evaluation, config: DetectionConfig, *, plots: bool,
           reporter: Reporter) -> None:
    """Everything into a hidden sibling of `out`, then renamed into place (`atomic_directory`; `_check_out` refused an
    `out` holding files without --overwrite)."""
    from nuparquet.atomic import atomic_directory

    with atomic_directory(out, overwrite=True, checked=True) as partial:
        _write_json(partial / SUMMARY_NAME, result.summary)
        _write_json(partial / DETAILS_NAME, result.details)
        for name, table in (("predictions", result.predictions), ("ground_truth", result.ground_truth)):
            (partial / name).mkdir()
            table.write_parquet(partial / name / "part-00000.parquet")
        if result.slices is not None:
            result.slices.write_parquet(partial / "slices.parquet")
            for (by, label), summary in result.slice_summaries.items():
                folder = partial / "slices" / slug(by) / slug(label)
                folder.mkdir(parents=True, exist_ok=True)
                _write_json(folder / SUMMARY_NAME, summary)
                _write_json(folder / DETAILS_NAME, result.slice_details[(by, label)])
        if plots:
            reporter.advance(step="plots")
            from nuparquet.evaluation.plots import write_plots

            write_plots(partial / "plots", whole.data, whole.metrics, config)
