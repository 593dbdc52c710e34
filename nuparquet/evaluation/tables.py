"""The evaluation as data: one row per predicted box (`predictions/`) and per evaluated-class ground-truth box
(`ground_truth/`), with what the evaluation made of it, so a user can ask polars why a model fails.

predictions/: sample_token, box_index (position in the sample's list in the submission), scene_name,
scene_token, timestamp (the sample's, microseconds), detection_name, detection_score, attribute_name,
translation, size, rotation, velocity (as submitted), ego_distance_m, evaluated (false: left out by a filter),
filtered_by (null, "range", "points" or "bike_rack"), rank (position in the devkit's processing order within
its class: descending score, ties to the later box; null when not evaluated); per threshold T (suffix
`threshold_suffix`, e.g. `_2m`, `_0_5m`): matched_gt_T (the annotation token, null for a false positive) and
match_distance_m_T; and the TP errors of its match at the TP threshold (trans_err, scale_err, orient_err,
vel_err, attr_err; null unless a true positive there).

ground_truth/: token (sample_annotation), sample_token, scene_name, timestamp, detection_name, attribute_name,
visibility_name, num_pts (lidar + radar), ego_distance_m, evaluated, filtered_by, and per threshold
matched_box_T (box_index of the prediction that took it, in the same sample; null: missed) and
match_distance_m_T.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.columns import to_series
from nuparquet.evaluation.classes import TP_METRICS
from nuparquet.evaluation.filters import KEPT, REASONS


def threshold_suffix(threshold: float) -> str:
    """Column-name suffix of a matching threshold: 0.5 -> "0_5m", 2.0 -> "2m"."""
    return f"{float(threshold):g}".replace(".", "_").replace("-", "minus") + "m"


def _strings(name: str, values: np.ndarray) -> pl.Series:
    """(N,) str/None object array as a String column (polars does not cast object arrays)."""
    return pl.Series(name, np.asarray(values, dtype=object).tolist(), dtype=pl.String)


def _reasons(reason: np.ndarray) -> pl.Series:
    return _strings("filtered_by", np.array(REASONS, dtype=object)[reason])


def _nullable(name: str, values: np.ndarray, valid: np.ndarray, dtype) -> pl.Series:
    series = pl.Series(name, values, dtype=dtype)
    return pl.select(pl.when(pl.Series(valid)).then(series)).to_series().alias(name)


def predictions_table(sub, pred_sample: np.ndarray, samples, ego_distance_m: np.ndarray, reason: np.ndarray,
                      kept_rows: np.ndarray, kept_class: np.ndarray, matches, errors_at_tp: dict,
                      tp_threshold_index: int, gt_tokens: np.ndarray) -> pl.DataFrame:
    """One row per submitted box, in the submission's order (see the module docstring).

    pred_sample: (N,) sample index of each box; kept_rows: (P,) the evaluated boxes' rows (the matches' rows
    index them), kept_class: (P,) their class index; errors_at_tp: (P,) arrays of TP errors (NaN where not a
    true positive at the TP threshold); gt_tokens: (G,) annotation token of each evaluated ground-truth box.
    """
    n = len(sub)
    rank = np.full(n, -1, dtype=np.int64)
    if len(kept_rows):
        ordered_class = kept_class[matches.order]
        class_start = np.searchsorted(ordered_class, ordered_class, "left")
        within_class = np.empty(len(kept_rows), dtype=np.int64)
        within_class[matches.order] = np.arange(len(kept_rows)) - class_start
        rank[kept_rows] = within_class
    columns = [
        _strings("sample_token", samples.token[pred_sample]),
        pl.Series("box_index", sub.box_index, dtype=pl.Int64),
        _strings("scene_name", samples.scene_name[pred_sample]),
        _strings("scene_token", samples.scene_token[pred_sample]),
        pl.Series("timestamp", samples.timestamp_us[pred_sample], dtype=pl.Int64),
        _strings("detection_name", sub.detection_name),
        pl.Series("detection_score", sub.detection_score, dtype=pl.Float64),
        _strings("attribute_name", sub.attribute_name),
        to_series("translation", sub.translation_m),
        to_series("size", sub.size_wlh_m),
        to_series("rotation", sub.rotation_wxyz),
        to_series("velocity", sub.velocity_mps),
        pl.Series("ego_distance_m", ego_distance_m, dtype=pl.Float64),
        pl.Series("evaluated", reason == KEPT, dtype=pl.Boolean),
        _reasons(reason),
        _nullable("rank", rank, rank >= 0, pl.Int64),
    ]
    for t, threshold in enumerate(matches.thresholds):
        suffix = threshold_suffix(threshold)
        gt_row = np.full(n, -1, dtype=np.int64)
        distance = np.full(n, np.nan)
        gt_row[kept_rows] = matches.gt[t]
        distance[kept_rows] = matches.distance_m[t]
        hit = gt_row >= 0
        token = np.full(n, None, dtype=object)
        token[hit] = gt_tokens[gt_row[hit]]
        columns.append(_strings(f"matched_gt_{suffix}", token))
        columns.append(_nullable(f"match_distance_m_{suffix}", distance, hit, pl.Float64))
    tp = np.zeros(n, dtype=bool)
    tp[kept_rows] = matches.gt[tp_threshold_index] >= 0
    for metric in TP_METRICS:
        values = np.full(n, np.nan)
        values[kept_rows] = errors_at_tp[metric]
        columns.append(_nullable(metric, values, tp & ~np.isnan(values), pl.Float64))
    return pl.DataFrame(columns)


def ground_truth_table(gt, ego_distance_m: np.ndarray, reason: np.ndarray, kept_rows: np.ndarray, matches,
                       pred_box_index: np.ndarray) -> pl.DataFrame:
    """One row per ground-truth box of an evaluated class (see the module docstring).

    kept_rows: (G,) rows of `gt` evaluated (the matches' ground-truth rows index them); pred_box_index: (P,)
    box_index of each evaluated prediction."""
    n = len(gt.boxes)
    table = gt.annotations.select("token", "sample_token", "scene_name", "timestamp", "detection_name")
    columns = [
        _strings("attribute_name", gt.boxes.attribute),
        *([gt.annotations["visibility_name"]] if "visibility_name" in gt.annotations.columns else []),
        pl.Series("num_pts", gt.boxes.num_pts, dtype=pl.Int64),
        pl.Series("ego_distance_m", ego_distance_m, dtype=pl.Float64),
        pl.Series("evaluated", reason == KEPT, dtype=pl.Boolean),
        _reasons(reason),
    ]
    for t, threshold in enumerate(matches.thresholds):
        suffix = threshold_suffix(threshold)
        box = np.full(n, -1, dtype=np.int64)
        distance = np.full(n, np.nan)
        hit = matches.gt[t] >= 0
        box[kept_rows[matches.gt[t, hit]]] = pred_box_index[hit]
        distance[kept_rows[matches.gt[t, hit]]] = matches.distance_m[t, hit]
        columns.append(_nullable(f"matched_box_{suffix}", box, box >= 0, pl.Int64))
        columns.append(_nullable(f"match_distance_m_{suffix}", distance, box >= 0, pl.Float64))
    return table.with_columns(columns)
