"""nuscenes-devkit's `PanopticEval` (eval/panoptic/panoptic_seg_evaluator.py) and
`NuScenesPanopticEval.wrap_result_segmentation`: per class the matched instances (IoU > 0.5, float64) and their
IoU sums, the unmatched ones of at least `min_inst_points` points, PQ = SQ * RQ, the semantic IoU from the
(pred, gt) confusion matrix (the ignore column zeroed, a class absent from both sides scores 0), and PQ-dagger
(thing PQ and stuff IoU averaged). The same numpy operations in the same order (a class's IoU sum: `np.sum` of its
matched IoUs ordered by ground truth then prediction, frame by frame), so every number is the devkit's bit for bit,
except PQ-dagger's last bits: the devkit averages in the order of a Python set of class names (hash-seeded), this
in class index order (docs/CONTRACTS.md)."""

from __future__ import annotations

import numpy as np

from nuparquet.evaluation.panoptic.segments import FrameSegments
from nuparquet.evaluation.segmentation.classes import (
    COARSE_NAMES,
    IGNORE_INDEX,
    NUM_CLASSES,
)

EPS = 1e-15  # PanopticEval.eps
INCLUDE = np.array([c for c in range(NUM_CLASSES) if c != IGNORE_INDEX], dtype=np.int64)
MIN_STUFF_INDEX = 11  # PanopticClassMapper: classes 1..10 are things, 11..16 stuff
THING_INDICES = tuple(range(1, MIN_STUFF_INDEX))
STUFF_INDICES = tuple(range(MIN_STUFF_INDEX, NUM_CLASSES))
IOU_THRESHOLD = 0.5
TERMS = (None, "TP", "FN", "FP")  # an instance's PQ term by code (None: unmatched, under min_inst_points)
NO_TERM, TP, FN, FP = range(len(TERMS))


def class_kind(index: int) -> str:
    return "ignore" if index == IGNORE_INDEX else "thing" if index < MIN_STUFF_INDEX else "stuff"


def semantic_iou(confusion: np.ndarray) -> tuple[float, np.ndarray]:
    """`PanopticEval.getSemIoU`: (mean IoU over the included classes, (C,) IoU per class) of the (pred, gt)
    confusion counts."""
    conf = confusion.astype(np.double)
    conf[:, IGNORE_INDEX] = 0
    tp = conf.diagonal()
    fp = conf.sum(axis=1) - tp
    fn = conf.sum(axis=0) - tp
    union = np.maximum(tp + fp + fn, EPS)
    iou = tp / union
    return (tp[INCLUDE] / union[INCLUDE]).mean(), iou


def quality_terms(tp: np.ndarray, iou_sum: np.ndarray, fp: np.ndarray, fn: np.ndarray):
    """`PanopticEval.getPQ`'s per-class (PQ, SQ, RQ), float64."""
    sq = iou_sum.astype(np.double) / np.maximum(tp.astype(np.double), EPS)
    rq = tp.astype(np.double) / np.maximum(tp.astype(np.double) + 0.5 * fp.astype(np.double)
                                           + 0.5 * fn.astype(np.double), EPS)
    return sq * rq, sq, rq


def dagger(per_class: dict, key: str) -> float:
    """The mean of the things' `key` (PQ or PTQ) and the stuff classes' IoU, in class index order."""
    values = [float(per_class[COARSE_NAMES[c]][key]) for c in THING_INDICES]
    return float(np.mean(values + [float(per_class[COARSE_NAMES[c]]["IoU"]) for c in STUFF_INDICES]))


class PanopticQuality:
    """The accumulated counts of `PanopticEval` over the frames added (`add`, in the devkit's sample order)."""

    def __init__(self, min_inst_points: int):
        self.min_inst_points = min_inst_points
        self.confusion = np.zeros((NUM_CLASSES, NUM_CLASSES), dtype=np.int64)
        self.tp = np.zeros(NUM_CLASSES, dtype=np.int64)
        self.iou_sum = np.zeros(NUM_CLASSES, dtype=np.double)
        self.fp = np.zeros(NUM_CLASSES, dtype=np.int64)
        self.fn = np.zeros(NUM_CLASSES, dtype=np.int64)

    def add(self, seg: FrameSegments) -> dict:
        """Count one frame (`addBatch`); returns its instances' terms: {"gt": ..., "pred": ...}, each a dict of
        arrays (index into the frame's ids, matched other side's index or -1, IoU or NaN, the code of its term in
        TERMS)."""
        self.confusion += seg.confusion
        pairs = np.flatnonzero(seg.same_class)
        gi, pi = seg.pair_gt[pairs], seg.pair_pred[pairs]
        inter = seg.pair_points[pairs]
        unions = seg.gt_points[gi] + seg.pred_points[pi] - inter
        ious = inter.astype(np.double) / unions.astype(np.double)
        tp = ious > IOU_THRESHOLD
        classes = seg.gt_class[gi]
        self.tp += np.bincount(classes[tp], minlength=NUM_CLASSES)
        for cl in np.unique(classes[tp]):  # per class, its matched IoUs in the devkit's order
            self.iou_sum[cl] += np.sum(ious[tp & (classes == cl)])
        gt_match = np.full(len(seg.gt_ids), -1, dtype=np.int64)
        gt_match[gi[tp]] = pi[tp]
        pred_match = np.full(len(seg.pred_ids), -1, dtype=np.int64)
        pred_match[pi[tp]] = gi[tp]
        gt_iou = np.full(len(seg.gt_ids), np.nan)
        gt_iou[gi[tp]] = ious[tp]
        pred_iou = np.full(len(seg.pred_ids), np.nan)
        pred_iou[pi[tp]] = ious[tp]
        fn = (gt_match < 0) & (seg.gt_points >= self.min_inst_points)
        instance = seg.pred_class != IGNORE_INDEX
        fp = (pred_match < 0) & (seg.pred_points >= self.min_inst_points) & instance
        self.fn += np.bincount(seg.gt_class[fn], minlength=NUM_CLASSES)
        self.fp += np.bincount(seg.pred_class[fp], minlength=NUM_CLASSES)
        return {"gt": {"index": np.arange(len(seg.gt_ids)), "match": gt_match, "iou": gt_iou,
                       "term": np.where(gt_match >= 0, TP, np.where(fn, FN, NO_TERM))},
                "pred": {"index": np.flatnonzero(instance), "match": pred_match[instance],
                         "iou": pred_iou[instance],
                         "term": np.where(pred_match >= 0, TP, np.where(fp, FP, NO_TERM))[instance]}}

    def metrics(self) -> dict:
        """`NuScenesPanopticEval.evaluate_segmentation`'s dict: {"all": {PQ, SQ, RQ, mIoU, PQ_dagger}, class name:
        {PQ, SQ, RQ, IoU} for every class in index order, "ignore" first}."""
        pq, sq, rq = quality_terms(self.tp, self.iou_sum, self.fp, self.fn)
        mean_iou, iou = semantic_iou(self.confusion)
        results = {"all": {"PQ": float(pq[INCLUDE].mean()), "SQ": float(sq[INCLUDE].mean()),
                           "RQ": float(rq[INCLUDE].mean()), "mIoU": float(mean_iou)}}
        for index, name in enumerate(COARSE_NAMES):
            results[name] = {"PQ": float(pq[index]), "SQ": float(sq[index]), "RQ": float(rq[index]),
                             "IoU": float(iou[index])}
        results["all"]["PQ_dagger"] = dagger(results, "PQ")
        return results
