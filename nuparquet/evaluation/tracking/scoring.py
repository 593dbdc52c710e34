"""One tracking evaluation of tracked boxes, class by class, as the devkit's `TrackingEval.evaluate`: the pairs
that can match, the accumulator with every prediction (whose MATCH scores give the recall thresholds), the
accumulator at each distinct threshold, the metric data and the label metrics."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from nuparquet.evaluation.boxes import Boxes
from nuparquet.evaluation.matching import candidate_pairs
from nuparquet.evaluation.tracking.accumulator import MATCH, Events, accumulate
from nuparquet.evaluation.tracking.config import TrackingConfig
from nuparquet.evaluation.tracking.metrics import (
    ClassMetricData, class_metric_data, label_metrics, recall_thresholds, run_metrics, summary,
)
from nuparquet.evaluation.tracking.tracks import TrackedBoxes


@dataclass(frozen=True)
class ClassEvaluation:
    """One class: its metric data, its rows of the tracked boxes (gt_rows, pred_rows), the events with every
    prediction kept (`every`, one run) and at the evaluated thresholds (`data.events`)."""

    data: ClassMetricData
    gt_rows: np.ndarray
    pred_rows: np.ndarray
    every: Events | None


@dataclass(frozen=True)
class TrackingEvaluation:
    classes: dict[str, ClassEvaluation]
    labels: dict
    eval_time_s: float
    num_gt: int
    num_predictions: int

    def summary(self, config: TrackingConfig, meta: dict) -> dict:
        return summary(self.labels, config, self.eval_time_s, meta)

    def details(self) -> dict:
        return {name: c.data.serialize() for name, c in self.classes.items()}


def devkit_distances_m(a_xy: np.ndarray, b_xy: np.ndarray) -> np.ndarray:
    """(K,) xy distances of K pairs as the devkit's `sklearn.metrics.pairwise.euclidean_distances` computes them:
    sqrt(max(-2 a.b + |a|^2 + |b|^2, 0)), term by term (its a.b is a BLAS product, which may fuse the multiply and
    add: the result agrees to ~1e-9 m at global coordinates, see docs/CONTRACTS.md)."""
    aa = a_xy[:, 0] * a_xy[:, 0] + a_xy[:, 1] * a_xy[:, 1]
    bb = b_xy[:, 0] * b_xy[:, 0] + b_xy[:, 1] * b_xy[:, 1]
    ab = a_xy[:, 0] * b_xy[:, 0] + a_xy[:, 1] * b_xy[:, 1]
    squared = -2 * ab
    squared += aa
    squared += bb
    return np.sqrt(np.maximum(squared, 0))


def _locate(boxes: TrackedBoxes) -> Boxes:
    """The fields `candidate_pairs` reads."""
    n = len(boxes)
    return Boxes(cuboids=boxes.cuboids, sample_index=boxes.sample, class_index=boxes.class_index,
                 velocity_mps=np.zeros((n, 2)),
                 attribute=np.zeros(n, object), score=boxes.score, num_pts=np.zeros(n, np.int64))


def possible_pairs(gt: TrackedBoxes, pred: TrackedBoxes, dist_th_m: float, num_classes: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(gt row, pred row, distance) of every pair of one sample and class the devkit could match: its distance
    below `dist_th_m` (distances >= the threshold are NaN in the devkit's matrix)."""
    margin = 1e-6 + 1e-9 * dist_th_m  # candidates by the exact distance, a little wider; the devkit's decides
    p, g, _ = candidate_pairs(_locate(gt), _locate(pred), dist_th_m + margin, num_classes)
    d = devkit_distances_m(gt.translation_m[g, :2], pred.translation_m[p, :2])
    keep = d < dist_th_m
    return g[keep], p[keep], d[keep]


def score_tracks(gt: TrackedBoxes, pred: TrackedBoxes, config: TrackingConfig, num_samples: int, positions: int
                 ) -> TrackingEvaluation:
    """Every class's metrics (`TrackingEval.evaluate`); the evaluation time goes into the summary."""
    start = time.perf_counter()
    names = config.class_names
    pair_gt, pair_pred, pair_d = possible_pairs(gt, pred, config.dist_th_tp, len(names))
    classes = {}
    for c, name in enumerate(names):
        gt_rows, pred_rows = np.flatnonzero(gt.class_index == c), np.flatnonzero(pred.class_index == c)
        if not len(gt_rows):  # the devkit adds no metric: every value NaN
            classes[name] = ClassEvaluation(ClassMetricData.no_ground_truth(config.num_thresholds), gt_rows,
                                            pred_rows, None)
            continue
        g_local = np.full(len(gt), -1, np.int64)
        g_local[gt_rows] = np.arange(len(gt_rows))
        p_local = np.full(len(pred), -1, np.int64)
        p_local[pred_rows] = np.arange(len(pred_rows))
        mine = np.flatnonzero(gt.class_index[pair_gt] == c)
        cg, cp, cd = g_local[pair_gt[mine]], p_local[pair_pred[mine]], pair_d[mine]
        cls_gt, cls_pred = gt.take(gt_rows), pred.take(pred_rows)
        every = accumulate(cls_gt, cls_pred, cg, cp, cd, np.array([-np.inf]), positions)
        match_rows = every.matched_pred[0][every.status[0] == MATCH]
        thresholds, recall_hypo = recall_thresholds(cls_pred.score[match_rows], len(gt_rows), config)
        valid = np.array([t for t in thresholds if not np.isnan(t)])
        run = events = evaluated = None
        if len(valid):
            evaluated = np.unique(valid)
            events = accumulate(cls_gt, cls_pred, cg, cp, cd, evaluated, positions)
            run = run_metrics(events, cls_gt, cls_pred, num_samples)
        gt_tracks = len(np.unique(cls_gt.track))
        data = class_metric_data(thresholds, recall_hypo, run, evaluated, config, len(gt_rows), gt_tracks)
        data = ClassMetricData(data.values, data.thresholds, data.run, events)
        classes[name] = ClassEvaluation(data, gt_rows, pred_rows, every)
    labels = label_metrics({name: c.data for name, c in classes.items()}, config)
    return TrackingEvaluation(classes, labels, time.perf_counter() - start, len(gt), len(pred))
