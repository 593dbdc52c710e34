"""The tracking evaluation as data: one row per ground-truth track and per predicted track, with what the
accumulator made of it at its class's best-MOTA threshold (the threshold metrics_summary.json's MOTA, MOTP, IDS,
FRAG... come from), so a user can ask polars which tracks switch, fragment or are never found.

tracks (ground truth): scene_name, instance_token, tracking_name, boxes (the track's frames, interpolated ones
included), interpolated, threshold (the class's best-MOTA score threshold; null: the class has no threshold),
matched, switches, missed (frames MATCHed, SWITCHed to, MISSed at that threshold), tracked_ratio (the share
motmetrics' mostly-tracked/lost use), first_tracked (frames before its first match, TID's count; null: never).

predicted_tracks: scene_name, tracking_id, tracking_name (of its first box), boxes, interpolated, score (the
track's mean, what the thresholds compare), threshold, kept (score at least the threshold), matched, switches
(frames where a ground-truth object switched to it), false_positives.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.evaluation.tracking.accumulator import MATCH, MISS, SWITCH
from nuparquet.evaluation.tracking.config import TrackingConfig


def _strings(name: str, values) -> pl.Series:
    return pl.Series(name, np.asarray(values, dtype=object).tolist(), dtype=pl.String)


def best_runs(evaluation) -> dict:
    """{class: (run index, threshold)} of the best-MOTA threshold (the devkit's choice), for classes that have one."""
    out = {}
    for name, c in evaluation.classes.items():
        data = c.data
        if data.events is None:
            continue
        mota = np.array(data.values["mota"], dtype=np.float64)
        if np.all(np.isnan(mota)):
            continue
        threshold = data.values["confidence"][int(np.nanargmax(mota))]
        out[name] = (int(np.searchsorted(data.thresholds, threshold)), float(threshold))
    return out


def _first_box_per_track(tracks, num_tracks: int) -> np.ndarray:
    order = np.lexsort((tracks.order, tracks.position, tracks.track))
    first = np.full(num_tracks, -1, np.int64)
    starts = np.r_[True, tracks.track[order][1:] != tracks.track[order][:-1]] if len(order) else np.zeros(0, bool)
    first[tracks.track[order][starts]] = order[starts]
    return first


def ground_truth_tracks(inputs, evaluation, gt_tracks, pred_tracks, config: TrackingConfig) -> pl.DataFrame:
    """One row per ground-truth track (module docstring)."""
    num = int(gt_tracks.track.max(initial=-1)) + 1
    counts = {key: np.zeros(num, np.int64) for key in ("matched", "switches", "missed")}
    threshold = np.full(num, np.nan)
    first_tracked = np.full(num, -1, np.int64)
    evaluated = np.zeros(num, bool)
    for name, (run, value) in best_runs(evaluation).items():
        c = evaluation.classes[name]
        status = c.data.events.status[run]
        track = gt_tracks.track[c.gt_rows]
        for key, code in (("matched", MATCH), ("switches", SWITCH), ("missed", MISS)):
            counts[key] += np.bincount(track, weights=status == code, minlength=num).astype(np.int64)
        threshold[np.unique(track)] = value
        evaluated[np.unique(track)] = True
        position = gt_tracks.position[c.gt_rows]
        start = np.full(num, np.iinfo(np.int64).max)
        np.minimum.at(start, track, position)
        hit = np.full(num, np.iinfo(np.int64).max)
        np.minimum.at(hit, track[status != MISS], position[status != MISS])
        found = hit < np.iinfo(np.int64).max
        first_tracked[found] = (hit - start)[found]
    first = _first_box_per_track(gt_tracks, num)
    boxes = np.bincount(gt_tracks.track, minlength=num)
    interpolated = np.bincount(gt_tracks.track, weights=gt_tracks.source < 0, minlength=num).astype(np.int64)
    scene_names = inputs.gt.scenes["name"].to_numpy().astype(object)
    instance = inputs.gt.annotations["instance_token"].to_numpy().astype(object)
    source = inputs.gt_kept[gt_tracks.source[first]]
    tracked = counts["matched"] + counts["switches"]
    return pl.DataFrame([
        _strings("scene_name", scene_names[gt_tracks.scene[first]]),
        _strings("instance_token", instance[source]),
        _strings("tracking_name", np.array(config.class_names, dtype=object)[gt_tracks.class_index[first]]),
        pl.Series("boxes", boxes, dtype=pl.Int64),
        pl.Series("interpolated", interpolated, dtype=pl.Int64),
        pl.Series("threshold", np.where(evaluated, threshold, np.nan)).fill_nan(None),
        *[pl.Series(key, values, dtype=pl.Int64) for key, values in counts.items()],
        pl.Series("tracked_ratio", np.where(evaluated, tracked / np.maximum(boxes, 1), np.nan)).fill_nan(None),
        pl.Series("first_tracked", first_tracked, dtype=pl.Int64).replace(-1, None),
    ])


def predicted_tracks(inputs, evaluation, gt_tracks, pred_tracks, config: TrackingConfig) -> pl.DataFrame:
    """One row per predicted track (module docstring)."""
    num = int(pred_tracks.track.max(initial=-1)) + 1
    counts = {key: np.zeros(num, np.int64) for key in ("matched", "switches", "false_positives")}
    threshold = np.full(num, np.nan)
    for name, (run, value) in best_runs(evaluation).items():
        c = evaluation.classes[name]
        events = c.data.events
        track = pred_tracks.track[c.pred_rows]
        active, matched = events.active[run], events.matched[run]
        counts["matched"] += np.bincount(track, weights=matched, minlength=num).astype(np.int64)
        counts["false_positives"] += np.bincount(track, weights=active & ~matched, minlength=num).astype(np.int64)
        switched = events.matched_pred[run][events.status[run] == SWITCH]
        counts["switches"] += np.bincount(track[switched], minlength=num).astype(np.int64)
        threshold[np.unique(track)] = value
    first = _first_box_per_track(pred_tracks, num)
    sub = inputs.sub
    source = inputs.pred_kept[pred_tracks.source[first]]
    scene_names = inputs.gt.scenes["name"].to_numpy().astype(object)
    score = pred_tracks.score[first]
    return pl.DataFrame([
        _strings("scene_name", scene_names[pred_tracks.scene[first]]),
        _strings("tracking_id", sub.labels["tracking_id"][source]),
        _strings("tracking_name", np.array(config.class_names, dtype=object)[pred_tracks.class_index[first]]),
        pl.Series("boxes", np.bincount(pred_tracks.track, minlength=num), dtype=pl.Int64),
        pl.Series("interpolated", np.bincount(pred_tracks.track, weights=pred_tracks.source < 0,
                                              minlength=num).astype(np.int64), dtype=pl.Int64),
        pl.Series("score", score, dtype=pl.Float64),
        pl.Series("threshold", threshold).fill_nan(None),
        pl.Series("kept", np.where(np.isnan(threshold), False, score >= threshold), dtype=pl.Boolean),
        *[pl.Series(key, values, dtype=pl.Int64) for key, values in counts.items()],
    ])
