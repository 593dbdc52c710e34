"""Greedy centre-distance matching, the devkit's `accumulate`, vectorised and exact.

The devkit, for each class and threshold t, walks the predictions by descending score (equal scores: the box
later in the submission first, from `sorted((score, i))[::-1]`), and gives each the nearest ground-truth box of
its sample and class not yet taken (equal distances: the box listed first in the sample), taking it if the
distance is below t (`min_dist < dist_th`). A box at distance >= t is never taken, so a prediction's match is
the first box, by (distance, listing order), among its candidates closer than t that no earlier prediction
took: the candidate pairs closer than t decide everything.

Those pairs are found for all samples and classes at once (each prediction against the ground truth of its
sample and class, in chunks), and the walk is replayed in rounds over all predictions: in each round every
unresolved prediction proposes its first candidate not yet taken, and the proposal stands when no earlier
unresolved prediction still has that box among its candidates (no earlier prediction can take it any more, so
the sequential walk gives it to this one). The earliest unresolved prediction always stands, so the rounds
end; in practice a few rounds resolve everything.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from nuparquet.evaluation.boxes import Boxes
from nuparquet.geometry.dots import rowwise_norm

PAIRS_PER_CHUNK = 1 << 22  # candidate (prediction, ground truth) pairs measured at once: bounds the memory


@dataclass(frozen=True)
class Matches:
    """The matches of P predictions at each of T thresholds.

    order: (P,) prediction rows in the devkit's processing order (by class, then descending score, then later
    box first). gt: (T, P) int64 ground-truth row matched by each prediction at each threshold, -1 for none.
    distance_m: (T, P) float64 centre distance of the match, NaN for none.
    """

    thresholds: tuple
    order: np.ndarray
    gt: np.ndarray
    distance_m: np.ndarray


def processing_order(pred: Boxes) -> np.ndarray:
    """(P,) rows in the devkit's order: by class, then descending score, then descending position."""
    position = np.arange(len(pred))
    return np.lexsort((-position, -pred.score, pred.class_index))


def candidate_pairs(gt: Boxes, pred: Boxes, max_distance_m: float, num_classes: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (prediction, ground truth) pair of the same sample and class closer than `max_distance_m`:
    (K,) prediction rows, (K,) ground-truth rows, (K,) xy centre distances (the devkit's `center_distance`:
    `np.linalg.norm` of the difference, through the machine's BLAS as the devkit's, `geometry.dots`).

    The ground truth is sorted on one number per box, its (sample, class) group's band plus its x (bands
    further apart than twice the distance), so each prediction finds by binary search the boxes of its group
    within `max_distance_m` in x; only those pairs are measured."""
    if not len(gt) or not len(pred):
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    pad = 1e-3  # the keys round at ~1e-7 m: a wider window, the exact distance decides
    x_min = min(gt.translation_m[:, 0].min(), pred.translation_m[:, 0].min())
    span = max(gt.translation_m[:, 0].max(), pred.translation_m[:, 0].max()) - x_min + 2 * (max_distance_m + pad) + 1
    gt_key = (gt.sample_index * num_classes + gt.class_index) * span + (gt.translation_m[:, 0] - x_min)
    gt_order = np.argsort(gt_key, kind="stable")
    sorted_keys = gt_key[gt_order]
    pred_key = (pred.sample_index * num_classes + pred.class_index) * span + (pred.translation_m[:, 0] - x_min)
    first = np.searchsorted(sorted_keys, pred_key - (max_distance_m + pad), "left")
    count = np.searchsorted(sorted_keys, pred_key + (max_distance_m + pad), "right") - first
    preds_out, gts_out, distances_out = [], [], []
    ends = np.cumsum(count)
    start = 0
    while start < len(pred):
        # predictions [start, stop) hold at most PAIRS_PER_CHUNK pairs (at least one prediction per chunk)
        budget = (ends[start - 1] if start else 0) + PAIRS_PER_CHUNK
        stop = max(start + 1, int(np.searchsorted(ends, budget, "right")))
        n = count[start:stop]
        p = np.repeat(np.arange(start, stop), n)
        offset = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
        g = gt_order[np.repeat(first[start:stop], n) + offset]
        distance = rowwise_norm(pred.translation_m[p, :2] - gt.translation_m[g, :2])
        near = distance < max_distance_m
        preds_out.append(p[near])
        gts_out.append(g[near])
        distances_out.append(distance[near])
        start = stop
    return np.concatenate(preds_out), np.concatenate(gts_out), np.concatenate(distances_out)


def greedy(rank: np.ndarray, gt: np.ndarray, num_preds: int, num_gt: int) -> np.ndarray:
    """The devkit's sequential matching, replayed in rounds (module docstring).

    Args:
        rank, gt: (K,) candidate pairs (prediction rank in processing order, ground-truth row), sorted by rank
            then by preference (distance, then ground-truth row).
    Returns:
        (num_preds,) ground-truth row matched by the prediction of each rank, -1 for none.
    """
    match = np.full(num_preds, -1, dtype=np.int64)
    taken = np.zeros(num_gt, dtype=bool)
    resolved = np.zeros(num_preds, dtype=bool)
    live_rank, live_gt = rank, gt
    sentinel = np.iinfo(np.int64).max
    while len(live_rank):
        first = np.r_[True, live_rank[1:] != live_rank[:-1]]  # each prediction's first live candidate
        proposer, proposed = live_rank[first], live_gt[first]
        earliest = np.full(num_gt, sentinel, dtype=np.int64)
        np.minimum.at(earliest, live_gt, live_rank)  # the earliest prediction still able to take each box
        stands = earliest[proposed] == proposer
        match[proposer[stands]] = proposed[stands]
        taken[proposed[stands]] = True
        resolved[proposer[stands]] = True
        keep = ~taken[live_gt] & ~resolved[live_rank]
        live_rank, live_gt = live_rank[keep], live_gt[keep]
    return match


def match_boxes(gt: Boxes, pred: Boxes, thresholds: Sequence[float], num_classes: int) -> Matches:
    """Match `pred` to `gt` at every threshold (see the module docstring)."""
    order = processing_order(pred)
    rank_of = np.empty(len(pred), dtype=np.int64)
    rank_of[order] = np.arange(len(pred))
    thresholds = tuple(thresholds)
    matched = np.full((len(thresholds), len(pred)), -1, dtype=np.int64)
    distance = np.full((len(thresholds), len(pred)), np.nan)
    if len(pred) and len(gt):
        pair_pred, pair_gt, pair_distance = candidate_pairs(gt, pred, max(thresholds), num_classes)
        pair_rank = rank_of[pair_pred]
        by_preference = np.lexsort((pair_gt, pair_distance, pair_rank))
        pair_rank, pair_gt, pair_distance = (pair_rank[by_preference], pair_gt[by_preference],
                                             pair_distance[by_preference])
        for t, threshold in enumerate(thresholds):
            near = pair_distance < threshold
            by_rank = greedy(pair_rank[near], pair_gt[near], len(pred), len(gt))
            matched[t, order] = by_rank
            hit = matched[t] >= 0
            distance[t, hit] = rowwise_norm(pred.translation_m[hit, :2] - gt.translation_m[matched[t, hit], :2])
    return Matches(thresholds=thresholds, order=order, gt=matched, distance_m=distance)
