"""From the accumulator's events to the devkit's tracking metrics, with its arithmetic: `compute_thresholds`
(the score thresholds of the recall levels), the motmetrics metrics of each threshold (`create_motmetrics` and the
devkit's own: MOTAR, custom MOTA/MOTP, FAF, FRAG, TID, LGD), `TrackingMetricData` (one value per recall level, a
threshold met twice repeated, unreached levels NaN or the worst value) and `TrackingMetrics` (the best-MOTA
threshold's values, AMOTA / AMOTP, the means and sums over classes).

The values keep the devkit's number types where metrics_details.json shows them: counts are integers unless a
NaN shares their list (numpy makes the list float), and the worst values are the configuration's numbers as
written.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from nuparquet.evaluation.tracking.accumulator import MATCH, MISS, SWITCH, Events
from nuparquet.evaluation.tracking.config import (
    AVERAGED_FROM, SUMMED_METRICS, TRACKING_METRICS, TrackingConfig,
)
from nuparquet.evaluation.tracking.tracks import TrackedBoxes

# devkit constants.MOT_METRIC_MAP: the per-threshold metrics kept, by their name in the files
THRESHOLD_METRICS = ("gt", "tp", "motar", "mota", "motp", "faf", "mt", "ml", "fp", "fn", "ids", "frag", "recall",
                     "tid", "lgd")
COUNT_METRICS = ("gt", "tp", "mt", "ml", "fp", "fn", "ids", "frag")  # integers in motmetrics' summary
# metrics_details.json: confidence and recall_hypo, then the devkit's `TrackingMetricData.metrics` (a set: its
# order changes with Python's string hashing from run to run; ours is TRACKING_METRICS' order)
DETAIL_METRICS = tuple(m for m in TRACKING_METRICS if m not in AVERAGED_FROM)
SAMPLE_PERIOD_S = 0.5  # the devkit's TID / LGD: frames times the nuScenes keyframe period


def recall_thresholds(match_scores: np.ndarray, gt_count: int, config: TrackingConfig) -> tuple[list, list]:
    """The devkit's `compute_thresholds`: the score at each recall level (min_recall .. 1 in num_thresholds steps),
    from the scores of the predictions that MATCHed with every prediction kept; NaN where the level is not
    reached. Both lists in the devkit's order: highest recall first."""
    n = config.num_thresholds
    if len(match_scores) == 0:
        return [np.nan] * n, [np.nan] * n
    scores = np.sort(np.asarray(match_scores, np.float64))[::-1]
    rec = np.array(range(1, len(scores) + 1)) / gt_count
    rec_interp = np.linspace(config.min_recall, 1, n).round(12)
    thresholds = np.interp(rec_interp, rec, scores, right=0)
    thresholds[rec_interp > np.max(rec)] = np.nan
    return thresholds.tolist()[::-1], rec_interp.tolist()[::-1]


@dataclass(frozen=True)
class RunMetrics:
    """motmetrics' summary of each run (R,) of one class: the THRESHOLD_METRICS, counts as int64."""

    values: dict


def run_metrics(events: Events, gt: TrackedBoxes, pred: TrackedBoxes, num_samples: int) -> RunMetrics:
    """The per-threshold metrics of every run (`mh.compute` with the devkit's metric functions)."""
    status, runs = events.status, len(events.thresholds)
    tracked = status != MISS
    tp = (status == MATCH).sum(axis=1)
    ids = (status == SWITCH).sum(axis=1)
    fn = (status == MISS).sum(axis=1)
    fp = (events.active & ~events.matched).sum(axis=1)
    gt_count = np.full(runs, len(gt), np.int64)
    detections = tp + ids
    distance_sum = np.where(tracked, events.distance_m, 0.0).sum(axis=1)
    # frames: samples with a ground-truth box of the class or a prediction kept by the run (motmetrics' RAW rows)
    present = np.zeros((runs, num_samples), bool)
    present[:, gt.sample] = True
    run_index, pred_row = np.nonzero(events.active)
    present[run_index, pred.sample[pred_row]] = True
    frames = present.sum(axis=1)
    per_object = _object_metrics(tracked, gt)
    with np.errstate(divide="ignore", invalid="ignore"):
        motp = np.where(detections == 0, np.nan, distance_sum / np.maximum(detections, 1))
        recall = detections / gt_count
        mota = np.maximum(0, 1.0 - (fn + ids + fp) / gt_count)
        # devkit motar: recall of the matches alone (switches excluded), alpha 1
        match_recall = tp / gt_count
        nominator = (fn + ids + fp) - (1 - match_recall) * gt_count
        denominator = match_recall * gt_count
        motar = np.where(denominator == 0, np.nan, np.maximum(0, 1 - 1.0 * nominator / denominator))
        faf = fp / frames * 100
    return RunMetrics({"gt": gt_count, "tp": tp, "motar": motar, "mota": mota, "motp": motp, "faf": faf,
                       "mt": per_object["mt"], "ml": per_object["ml"], "fp": fp, "fn": fn, "ids": ids,
                       "frag": per_object["frag"], "recall": recall, "tid": per_object["tid"],
                       "lgd": per_object["lgd"]})


def _object_metrics(tracked: np.ndarray, gt: TrackedBoxes) -> dict:
    """Per run: mostly tracked / lost (tracked share >= 0.8 / < 0.2), fragmentations (tracked -> missed
    transitions before the object's last tracked frame), TID (frames from an object's first box to its first
    tracked one) and LGD (its longest run of missed frames), both x 0.5 s and averaged over the objects tracked
    at least once (NaN without). An object's boxes are consecutive frames (the ground truth is interpolated)."""
    runs = len(tracked)
    order = np.lexsort((gt.position, gt.track))
    track = gt.track[order]
    counts = np.bincount(track)
    present = counts > 0
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    t = tracked[:, order]  # (R, G) by object, then time
    within = np.arange(len(order)) - starts[track]
    hits = np.add.reduceat(t.astype(np.int64), starts[present], axis=1) if len(order) else np.zeros((runs, 0), np.int64)
    n = counts[present]
    ratio = hits / n
    mt = (ratio >= 0.8).sum(axis=1)
    ml = (ratio < 0.2).sum(axis=1)
    big = len(order) + 1
    first_hit = np.minimum.reduceat(np.where(t, within, big), starts[present], axis=1) if len(order) else \
        np.zeros((runs, 0), np.int64)
    last_hit = np.maximum.reduceat(np.where(t, within, -1), starts[present], axis=1) if len(order) else \
        np.zeros((runs, 0), np.int64)
    object_of = np.cumsum(present) - 1  # object column of each track
    col = object_of[track]
    # fragmentations: j where tracked at j-1, missed at j, and j before the last tracked frame
    previous = np.zeros_like(t)
    previous[:, 1:] = t[:, :-1]
    start_of_miss = ~t & previous & (within > 0)[None, :] & (within[None, :] < last_hit[:, col])
    frag = start_of_miss.sum(axis=1)
    # longest run of misses of each object (over its whole span): at a missed frame, the frames since the
    # object's last tracked one (or its first frame)
    place = np.arange(t.shape[1])
    last_tracked = np.maximum.accumulate(np.where(t, place[None, :], -1), axis=1) if t.shape[1] else t.astype(int)
    since = np.maximum(last_tracked, (starts[track] - 1)[None, :])
    run_length = np.where(t, 0, place[None, :] - since)
    gap = np.maximum.reduceat(run_length, starts[present], axis=1) if len(order) else np.zeros((runs, 0), np.int64)
    hit_any = hits > 0
    matched_tracks = hit_any.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tid = np.where(matched_tracks == 0, np.nan,
                       (np.where(hit_any, first_hit, 0).sum(axis=1) * SAMPLE_PERIOD_S) / matched_tracks)
        lgd = np.where(matched_tracks == 0, np.nan,
                       (np.where(hit_any, gap, 0).sum(axis=1) * SAMPLE_PERIOD_S) / matched_tracks)
    return {"mt": mt, "ml": ml, "frag": frag, "tid": tid, "lgd": lgd}


@dataclass(frozen=True)
class ClassMetricData:
    """The devkit's `TrackingMetricData` of one class: `values` {confidence, recall_hypo, *DETAIL_METRICS: list of
    num_thresholds Python numbers}, highest recall level first; `runs`: the thresholds evaluated (ascending,
    each once) with their RunMetrics and Events (None without ground truth or without a match)."""

    values: dict
    thresholds: np.ndarray | None = None
    run: RunMetrics | None = None
    events: Events | None = None

    def serialize(self) -> dict:
        return {name: list(self.values[name]) for name in ("confidence", "recall_hypo", *DETAIL_METRICS)}

    @classmethod
    def no_ground_truth(cls, n: int) -> ClassMetricData:
        return cls({name: [np.nan] * n for name in ("confidence", "recall_hypo", *DETAIL_METRICS)})


def class_metric_data(thresholds: list, recall_hypo: list, run: RunMetrics | None, evaluated: np.ndarray | None,
                      config: TrackingConfig, gt_count: int, gt_tracks: int) -> ClassMetricData:
    """The devkit's `TrackingEvaluation.accumulate` from the recall thresholds and the metrics of each distinct
    threshold (`evaluated`, ascending; None when no level was reached): values repeated for a threshold reached by
    several levels, NaN first for the levels not reached; every value the worst one when none was."""
    n = config.num_thresholds
    values = {"confidence": list(thresholds), "recall_hypo": list(recall_hypo)}
    if run is None:
        for name in DETAIL_METRICS:
            worst = config.metric_worst[name]
            if worst == -1:
                worst = {"ml": gt_tracks, "gt": gt_count, "fn": gt_count}.get(name, np.nan)
                if name not in ("ml", "gt", "fn", "fp", "ids", "frag"):
                    raise NotImplementedError(f"metric_worst[{name!r}] = -1 has no meaning for {name}")
            values[name] = [worst] * n
        return ClassMetricData(values)
    levels = np.asarray(thresholds, np.float64)
    repeats = np.array([np.sum(levels == t) for t in evaluated])
    unreached = int(np.isnan(levels).sum())
    for name in DETAIL_METRICS:
        per_threshold = np.repeat(run.values[name], repeats)
        column = np.concatenate([np.full(unreached, np.nan), per_threshold]) if unreached else per_threshold
        values[name] = column.tolist()  # int64 stays integers, a NaN makes the list float (numpy's array)
    return ClassMetricData(values, evaluated, run)


def label_metrics(data: dict[str, ClassMetricData], config: TrackingConfig) -> dict:
    """The devkit's `TrackingMetrics.label_metrics`: {metric: {class: float}} in TRACKING_METRICS order, classes
    sorted: the threshold of best MOTA (the first of equals) gives the traditional metrics, AMOTA / AMOTP average
    MOTAR / MOTP over the recall levels with the worst value where a level is not reached."""
    out = {metric: {name: np.nan for name in config.class_names} for metric in TRACKING_METRICS}
    for name in config.class_names:
        md = data[name].values
        mota = np.array(md["mota"], dtype=np.float64)
        if not np.all(np.isnan(mota)):
            best = int(np.nanargmax(mota))
            for metric in THRESHOLD_METRICS:
                out[metric][name] = float(md[metric][best])
        for metric, source in AVERAGED_FROM.items():
            values = np.array(md[source], dtype=np.float64)
            if np.all(np.isnan(values)):
                out[metric][name] = np.nan
            else:
                values[np.isnan(values)] = config.metric_worst[metric]
                out[metric][name] = float(np.nanmean(values))
    return out


def summary(labels: dict, config: TrackingConfig, eval_time_s: float, meta: dict) -> dict:
    """metrics_summary.json: the devkit's `TrackingMetrics.serialize()` and the submission's meta."""
    out = {"label_metrics": labels, "eval_time": eval_time_s, "cfg": config.serialize()}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # nanmean of a metric no class has: NaN, as the devkit
        for metric, per_class in labels.items():
            data = list(per_class.values())
            out[metric] = float(np.nansum(data)) if metric in SUMMED_METRICS else float(np.nanmean(data))
    out["meta"] = dict(meta)
    return out

