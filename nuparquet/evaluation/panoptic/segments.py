"""One lidar frame's segments as nuscenes-devkit's panoptic evaluators see them (`PanopticEval.addBatch`,
`PanopticTrackingEval.add_batch`), computed once per frame instead of once per class.

The devkit compares, per class, ground-truth instances (the raw label `category index * 1000 + id`, + 1) with
predicted ones (the predicted label + 1), after dropping the points whose ground-truth class is the ignore class.
A label determines its class (ground truth: the class mapper of `label // 1000`; prediction: `label // 1000`), so
the per-class instances are the frame's distinct labels, and the per-class intersections are the pairs of labels
of the same class: one count of distinct values and one of distinct (ground truth, prediction) pairs, ordered as
the devkit's `np.unique(pred + 2**32 * gt)` orders them (by ground truth, then prediction)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.evaluation.segmentation.classes import IGNORE_INDEX, NUM_CLASSES



@dataclass
class FrameSegments:
    """confusion: (C, C) int64 points predicted as class (row) of ground-truth class (column), every point (the
    devkit's `px_iou_conf_matrix` orientation); gt_ids, pred_ids: sorted distinct labels + 1 of the points whose
    ground truth is not ignored, with their point counts and classes; pair_gt, pair_pred: indices into those of
    every distinct (ground truth, prediction) pair, by ground truth then prediction, and pair_points."""

    confusion: np.ndarray
    gt_ids: np.ndarray
    gt_points: np.ndarray
    gt_class: np.ndarray
    pred_ids: np.ndarray
    pred_points: np.ndarray
    pred_class: np.ndarray
    pair_gt: np.ndarray
    pair_pred: np.ndarray
    pair_points: np.ndarray

    @property
    def same_class(self) -> np.ndarray:
        """(K,) bool: the pairs the devkit intersects (both of one class; never the ignore class)."""
        return self.gt_class[self.pair_gt] == self.pred_class[self.pair_pred]


def _distinct(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ids, counts, index of each value into ids) of small non-negative integers (labels + 1, below 2**16 + 1):
    a bincount, the same sorted distinct values and counts as np.unique, without its sort."""
    counts = np.bincount(values)
    present = counts > 0  # nonzero of a bool mask: several times faster than of the counts
    ids = np.flatnonzero(present)
    rank = np.cumsum(present) - 1  # each value's index among the distinct ones
    return ids, counts[ids], rank[values]


def frame_segments(gt: np.ndarray, pred: np.ndarray, gt_class_of: np.ndarray) -> FrameSegments:
    """The segments of one frame. `gt`, `pred`: (P,) int64 raw panoptic labels (predictions checked to be of a
    class 0..16: `submission.read_predictions`); `gt_class_of`: (F,) the coarse class of each fine category index
    (every index `gt // 1000` uses checked to map)."""
    gt_sem = gt_class_of[gt // 1000]
    pred_sem = pred // 1000
    confusion = np.bincount(pred_sem * NUM_CLASSES + gt_sem,
                            minlength=NUM_CLASSES * NUM_CLASSES).reshape(NUM_CLASSES, NUM_CLASSES)
    keep = gt_sem != IGNORE_INDEX
    gt_ids, gt_points, gt_rank = _distinct(gt[keep] + 1)
    pred_ids, pred_points, pred_rank = _distinct(pred[keep] + 1)
    width = max(len(pred_ids), 1)
    key = gt_rank * width + pred_rank  # sorted keys: by ground truth, then prediction
    if len(gt_ids) * width <= max(4 * len(key), 1 << 16):
        pairs = np.bincount(key)
        found = np.flatnonzero(pairs > 0)
        pair_points = pairs[found]
    else:  # very many instances on both sides: a sort instead of a table of every combination
        found, pair_points = np.unique(key, return_counts=True)
    return FrameSegments(confusion=confusion, gt_ids=gt_ids, gt_points=gt_points,
                         gt_class=gt_class_of[(gt_ids - 1) // 1000], pred_ids=pred_ids, pred_points=pred_points,
                         pred_class=(pred_ids - 1) // 1000, pair_gt=found // width, pair_pred=found % width,
                         pair_points=pair_points)
