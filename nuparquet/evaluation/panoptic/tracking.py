"""nuscenes-devkit's `PanopticTrackingEval` (eval/panoptic/panoptic_track_evaluator.py) and
`NuScenesPanopticEval.wrap_result_mopt`: frame by frame within each scene, the instances matched per class with
float32 IoUs (> 0.5) and their float32-summed IoUs, identity switches of thing instances between consecutive
frames (and their float32 IoU sums: sPTQ), and per scene the class-agnostic association of thing instances of
more than `min_inst_points` points (LSTQ's S_assoc, PAT's TQ). Ported operation for operation, in the devkit's
iteration orders (dict insertion orders included), so every number is the devkit's bit for bit except
PTQ-dagger's last bits (`quality.dagger`); the float32 sums are numpy's (docs/CONTRACTS.md)."""

from __future__ import annotations

import itertools
import warnings

import numpy as np

from nuparquet.errors import InputError
from nuparquet.evaluation.panoptic.quality import (
    EPS,
    INCLUDE,
    IOU_THRESHOLD,
    MIN_STUFF_INDEX,
    dagger,
    quality_terms,
    semantic_iou,
)
from nuparquet.evaluation.panoptic.segments import FrameSegments
from nuparquet.evaluation.segmentation.classes import (
    COARSE_NAMES,
    IGNORE_INDEX,
    NUM_CLASSES,
)

UNMATCHED = 1  # the devkit's prediction id for "no match" (and, after its + 1, the ignore class's label 0)


class _Scene:
    """One scene's association state, keyed as the devkit keys it (labels + 1). The devkit keeps one dict per
    class; a ground-truth label determines its class (`gt_class`), so one dict in first-seen order holds each
    class's dict in its own order (a frame adds its instances by label, which orders them by class too)."""

    def __init__(self):
        self.gt_class: dict[int, int] = {}  # thing instances seen with > min points: their class
        self.gt_points: dict[int, int] = {}  # `gts`: those instances' summed points
        self.pred_points: dict[int, int] = {}  # `preds`: thing predictions of > min points, their summed points
        self.intersections: dict[tuple[int, int], int] = {}  # `intersects`: (gt, pred of any class) -> points
        self.pred_frames: dict[int, int] = {}  # `instance_preds`: predictions of > min points, frames seen
        self.gt_matches: dict[int, list] = {}  # `instance_gts`: gt -> its matched prediction per frame
        self.previous: tuple[np.ndarray, np.ndarray] | None = None  # the last frame's matched things: gt, pred

    def of_class(self, stats: dict, cl: int) -> list:
        """The (gt, value) items of `stats` whose instance is of class `cl`, in first-seen order."""
        return [(g, value) for g, value in stats.items() if self.gt_class[g] == cl]


def _accumulate(stats: dict, keys, values: np.ndarray) -> None:
    """The devkit's `update_dict_stat`: add each value to its key's total (a new key goes last)."""
    for key, value in zip(keys.tolist() if isinstance(keys, np.ndarray) else keys, values.tolist()):
        stats[key] = stats.get(key, 0) + value


class PanopticTracking:
    """The accumulated state of `PanopticTrackingEval` over the frames added (`add`, scene by scene in the
    devkit's order, each scene's frames in time order)."""

    def __init__(self, min_inst_points: int):
        self.min_inst_points = min_inst_points
        self.confusion = np.zeros((NUM_CLASSES, NUM_CLASSES), dtype=np.int64)
        self.tp = np.zeros(NUM_CLASSES, dtype=np.int64)
        self.iou_sum = np.zeros(NUM_CLASSES, dtype=np.double)
        self.fp = np.zeros(NUM_CLASSES, dtype=np.int64)
        self.fn = np.zeros(NUM_CLASSES, dtype=np.int64)
        self.switches = np.zeros(NUM_CLASSES, dtype=np.int64)
        self.soft_switches = np.zeros(NUM_CLASSES, dtype=np.double)
        self.scenes: dict[str, _Scene] = {}

    def add(self, scene_name: str, seg: FrameSegments) -> None:
        """Count one frame of scene `scene_name` (`add_batch`; its previous frame is the last one added for it)."""
        scene = self.scenes.setdefault(scene_name, _Scene())
        minimum = self.min_inst_points
        self.confusion += seg.confusion
        seen = seg.pred_points > minimum
        _accumulate(scene.pred_frames, seg.pred_ids[seen], np.ones(int(seen.sum()), dtype=np.int64))
        pairs = np.flatnonzero(seg.same_class)
        gi, pi = seg.pair_gt[pairs], seg.pair_pred[pairs]
        inter = seg.pair_points[pairs]
        ious = inter.astype(np.float32) / (seg.gt_points[gi] + seg.pred_points[pi] - inter).astype(np.float32)
        tp = ious > IOU_THRESHOLD
        classes = seg.gt_class[gi]
        self.tp += np.bincount(classes[tp], minlength=NUM_CLASSES)
        for cl in np.unique(classes[tp]):
            self.iou_sum[cl] += np.sum(ious[tp & (classes == cl)])  # a float32 sum, as the devkit's
        matched_gt = np.zeros(len(seg.gt_ids), dtype=bool)
        matched_gt[gi[tp]] = True
        matched_pred = np.zeros(len(seg.pred_ids), dtype=bool)
        matched_pred[pi[tp]] = True
        self.fn += np.bincount(seg.gt_class[~matched_gt & (seg.gt_points >= minimum)], minlength=NUM_CLASSES)
        fp = ~matched_pred & (seg.pred_points >= minimum) & (seg.pred_class != IGNORE_INDEX)
        self.fp += np.bincount(seg.pred_class[fp], minlength=NUM_CLASSES)
        things = tp & (classes < MIN_STUFF_INDEX)  # by ground truth, then prediction: as each class's own order
        current = (seg.gt_ids[gi[things]], seg.pred_ids[pi[things]], ious[things], classes[things])
        if scene.previous is not None:
            self._count_switches(scene.previous, current)
        scene.previous = current[:2]
        self._associate(scene, seg)

    def _count_switches(self, previous, current) -> None:
        """Matched thing instances of both frames whose matched prediction changed; per class their IoUs summed in
        float32 from a Python 0.0, in label order, as the devkit's loop does."""
        gt_prev, pred_prev = previous
        gt_cur, pred_cur, iou_cur, class_cur = current
        _, prev_ind, cur_ind = np.intersect1d(gt_prev, gt_cur, return_indices=True)
        switched = cur_ind[pred_prev[prev_ind] != pred_cur[cur_ind]]
        self.switches += np.bincount(class_cur[switched], minlength=NUM_CLASSES)
        for cl in np.unique(class_cur[switched]):
            soft = 0.0
            for iou in iou_cur[switched[class_cur[switched] == cl]]:
                soft += iou
            self.soft_switches[cl] += soft

    def _associate(self, scene: _Scene, seg: FrameSegments) -> None:
        """The class-agnostic part of `get_panoptic_track_stats`, every thing class at once."""
        minimum = self.min_inst_points
        thing = (seg.gt_class < MIN_STUFF_INDEX) & (seg.gt_points > minimum)
        scene.gt_class.update(zip(seg.gt_ids[thing].tolist(), seg.gt_class[thing].tolist()))
        _accumulate(scene.gt_points, seg.gt_ids[thing], seg.gt_points[thing])
        preds = (seg.pred_class != IGNORE_INDEX) & (seg.pred_class < MIN_STUFF_INDEX) & (seg.pred_points > minimum)
        _accumulate(scene.pred_points, seg.pred_ids[preds], seg.pred_points[preds])
        pairs = np.flatnonzero(thing[seg.pair_gt])  # with predictions of every class
        gi, pi = seg.pair_gt[pairs], seg.pair_pred[pairs]
        inter = seg.pair_points[pairs]
        gt_ids, pred_ids = seg.gt_ids[gi], seg.pred_ids[pi]
        _accumulate(scene.intersections, zip(gt_ids.tolist(), pred_ids.tolist()), inter)
        ious = inter.astype(np.float32) / (seg.gt_points[gi] + seg.pred_points[pi] - inter).astype(np.float32)
        tp = ious > IOU_THRESHOLD
        matches = scene.gt_matches
        for g, p in zip(gt_ids[tp].tolist(), pred_ids[tp].tolist()):
            matches.setdefault(g, []).append(p)
        matched = set(gt_ids[tp].tolist())
        for g in seg.gt_ids[thing].tolist():
            if g not in matched:
                matches.setdefault(g, []).append(UNMATCHED)

    def metrics(self) -> dict:
        """`NuScenesPanopticEval.evaluate_tracking`'s dict: {"all": {PAT, PQ, TQ, PTQ, sPTQ, LSTQ, mIoU, S_assoc,
        MOTSA, sMOTSA, MOTSP, PTQ_dagger}, class name: {PTQ, sPTQ, IoU} for every class in index order}.

        Raises InputError where the devkit divides by zero and fails: no thing instance of more than
        min_inst_points points in any frame (its TQ has no instance to average)."""
        with warnings.catch_warnings(), np.errstate(divide="ignore", invalid="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)  # the devkit's means of no class are NaN
            pat, pq, tq = self._pat()
            ptq, ptq_all, sptq, sptq_all = self._ptq()
            mean_iou, iou = semantic_iou(self.confusion)
            lstq, s_assoc = self._lstq(mean_iou)
            motsa, smotsa, motsp = self._motsa()
        results = {"all": {"PAT": float(pat), "PQ": float(pq), "TQ": float(tq), "PTQ": float(ptq),
                           "sPTQ": float(sptq), "LSTQ": float(lstq), "mIoU": float(mean_iou),
                           "S_assoc": float(s_assoc), "MOTSA": float(motsa), "sMOTSA": float(smotsa),
                           "MOTSP": float(motsp)}}
        for index, name in enumerate(COARSE_NAMES):
            results[name] = {"PTQ": float(ptq_all[index]), "sPTQ": float(sptq_all[index]), "IoU": float(iou[index])}
        results["all"]["PTQ_dagger"] = dagger(results, "PTQ")
        return results

    def _pat(self):
        pq_all, _, _ = quality_terms(self.tp, self.iou_sum, self.fp, self.fn)
        pq = pq_all[INCLUDE].mean()
        accumulate_tq, accumulate_norm = 0.0, 0
        for scene in self.scenes.values():
            for cl in INCLUDE:
                for _, pr_ids in scene.of_class(scene.gt_matches, cl):
                    unique_pr_id, counts_pr_id = np.unique(pr_ids, return_counts=True)
                    track_length = len(pr_ids)
                    keep = unique_pr_id != UNMATCHED
                    unique_pr_id, counts_pr_id = unique_pr_id[keep], counts_pr_id[keep]
                    fp_pr_id = np.array([scene.pred_frames[uid] - counts_pr_id[i] if uid in scene.pred_frames else 0
                                         for i, uid in enumerate(unique_pr_id.tolist())])
                    gt_id_aq = np.sum(counts_pr_id ** 2 / np.double(track_length + fp_pr_id)) / np.double(track_length)
                    gt_id_is = 1.0
                    if track_length > 1:
                        switches = sum(1 for before, after in itertools.pairwise(pr_ids)
                                       if after != before or before == UNMATCHED)
                        gt_id_is = 1 - (switches / np.double(track_length - 1))
                    accumulate_tq += np.sqrt(gt_id_aq * gt_id_is)
                    accumulate_norm += 1
        if accumulate_norm == 0:
            raise InputError(f"no ground-truth thing instance has more than min_inst_points={self.min_inst_points} "
                             "points in any frame of the split: the devkit's TQ (PAT) averages over none and fails")
        tq = np.array(accumulate_tq / accumulate_norm)
        return (2 * pq * tq) / (pq + tq), pq, tq

    def _ptq(self):
        iou = self.iou_sum.astype(np.double)
        ids, soft_ids = self.switches.astype(np.double), self.soft_switches.astype(np.double)
        tp, fp = self.tp.astype(np.double), self.fp.astype(np.double)
        tp_eps, fn = np.maximum(tp, EPS), self.fn.astype(np.double)
        tp_half_fp_half_fn_eps = np.maximum(tp + 0.5 * fp + 0.5 * fn, EPS)
        ptq_all = ((iou - ids) / tp_eps) * (tp / tp_half_fp_half_fn_eps)
        soft_ptq_all = ((iou - soft_ids) / tp_eps) * (tp / tp_half_fp_half_fn_eps)
        valid = (tp + fn) > 0.5
        valid[IGNORE_INDEX] = False
        return ptq_all[valid].mean(), ptq_all, soft_ptq_all[valid].mean(), soft_ptq_all

    def _motsa(self):
        things = slice(1, MIN_STUFF_INDEX)
        iou = self.iou_sum[things].astype(np.double)
        ids = self.switches[things].astype(np.double)
        tp, fp = self.tp[things].astype(np.double), self.fp[things].astype(np.double)
        tp_eps, fn = np.maximum(tp, EPS), self.fn[things].astype(np.double)
        valid = (tp + fn) > 0.5
        motsa = (tp - fp - ids)[valid] / (tp_eps + fn)[valid]
        s_motsa = (iou - fp - ids)[valid] / (tp_eps + fn)[valid]
        motsp = iou[valid] / tp_eps[valid]
        return motsa.mean(), s_motsa.mean(), motsp.mean()

    def _lstq(self, mean_iou):
        """(LSTQ, S_assoc): per scene and thing instance, the IoU-weighted intersections with each prediction, in
        the order the predictions were first counted (the devkit's loop over its `preds` dict)."""
        num_tubes = [0] * NUM_CLASSES
        association = np.zeros(NUM_CLASSES, dtype=np.double)
        for scene in self.scenes.values():
            rank = {p: i for i, p in enumerate(scene.pred_points)}
            by_gt: dict[int, list] = {}
            for (g, p), points in scene.intersections.items():
                if p in rank:
                    by_gt.setdefault(g, []).append((rank[p], p, points))
            for cl in INCLUDE:
                gts = scene.of_class(scene.gt_points, cl)
                num_tubes[cl] += len(gts)
                outer_sum_iou = 0.0
                for g, gt_size in gts:
                    inner_sum_iou = 0.0
                    for _, p, tpa in sorted(by_gt.get(g, ())):
                        pr_size = scene.pred_points[p]
                        inner_sum_iou += np.int64(tpa) * (np.int64(tpa) / np.int64(gt_size + pr_size - tpa))
                    outer_sum_iou += inner_sum_iou / float(gt_size)
                association[cl] += outer_sum_iou
        s_assoc = np.sum(association) / np.sum(num_tubes[1:MIN_STUFF_INDEX])
        return np.sqrt(s_assoc * mean_iou), s_assoc
