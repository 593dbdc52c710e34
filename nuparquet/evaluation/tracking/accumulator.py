"""The matching of the devkit's tracking evaluation: motmetrics 1.4.0's `MOTAccumulator.update`, frame by frame, as
the devkit's `accumulate_threshold` feeds it, replayed for many score thresholds and every scene at once.

What motmetrics does in one frame of a scene (the ground truth of one class, the predictions of that class scoring
at least the threshold; a pair can match when its centre distance is below `dist_th_tp`; state: the hypothesis
each object was last matched to, kept for the whole scene):
1. each object, in the frame's order, that was last matched to a hypothesis present and not yet taken in this
   frame takes it again if they can match (MATCH);
2. the objects and hypotheses left are assigned by `linear_sum_assignment` on the distance matrix, the pairs that
   cannot match replaced by motmetrics' "expensive edge" (2 r c + 1) and dropped from the result: a maximum set
   of possible pairs with the least total distance. A pair is a SWITCH when the object was last matched to
   another hypothesis, else a MATCH;
3. the objects left are MISSes, the hypotheses left false positives.

Here the frames at one position of their scene are processed together for every scene and every threshold
("run"), with numpy: step 1 over all pairs at once (an object claims the hypothesis it last matched; of several
objects claiming one hypothesis the first in the frame wins, as in motmetrics' loop). In step 2, a frame whose
remaining possible pairs share no object and no hypothesis has one answer, all of them (the only maximum
matching); only a frame where some object or hypothesis has two possible partners goes to SciPy's
`linear_sum_assignment`, on the same matrix, transformed the same way, that motmetrics gives its default solver
(scipy: motmetrics picks lapsolver or lap first when they are installed, whose ties may fall otherwise; see
docs/CONTRACTS.md), so its choice among equal-cost assignments is motmetrics' own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from nuparquet.evaluation.tracking.tracks import TrackedBoxes

MISS, MATCH, SWITCH = 0, 1, 2


@dataclass(frozen=True)
class Events:
    """What the accumulator made of each ground-truth box and each prediction of one class in each run.

    thresholds: (R,) the runs' score thresholds (ascending; -inf: every prediction). status: (R, G) int8 MISS /
    MATCH / SWITCH of each ground-truth box; distance_m: (R, G) the matched pair's distance (NaN for a miss);
    matched_pred: (R, G) the prediction row matched (-1); active: (R, P) the prediction scores at least the
    threshold; matched: (R, P) it was matched (MATCH or SWITCH)."""

    thresholds: np.ndarray
    status: np.ndarray
    distance_m: np.ndarray
    matched_pred: np.ndarray
    active: np.ndarray
    matched: np.ndarray
    solver_frames: int = 0  # frames sent to linear_sum_assignment (for the profile)


def expensive_edges(costs: np.ndarray) -> np.ndarray:
    """motmetrics' `add_expensive_edges`: NaN / inf entries replaced by 2 r c + 1 (r the smaller side, c one more
    than the largest finite |cost|), zeros when nothing is finite."""
    valid = np.isfinite(costs)
    if valid.all():
        return costs.copy()
    if not valid.any():
        return np.zeros_like(costs)
    r = min(costs.shape)
    c = np.abs(costs[valid]).max() + 1
    return np.where(valid, costs, 2 * r * c + 1)


def solve_frame(costs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """motmetrics' `linear_sum_assignment(costs)` with its scipy solver: (rows, columns) of the possible pairs."""
    if not costs.size:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    rows, cols = linear_sum_assignment(expensive_edges(costs))
    keep = np.isfinite(costs[rows, cols])
    return rows[keep].astype(np.int64), cols[keep].astype(np.int64)


def _by_position(boxes: TrackedBoxes, positions: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows ordered by (position, scene, order in sample), and the (positions + 1,) offsets of each position."""
    order = np.lexsort((boxes.order, boxes.scene, boxes.position))
    start = np.searchsorted(boxes.position[order], np.arange(positions + 1), "left")
    return order, start


def accumulate(gt: TrackedBoxes, pred: TrackedBoxes, pair_gt: np.ndarray, pair_pred: np.ndarray,
               pair_distance_m: np.ndarray, thresholds: np.ndarray, positions: int) -> Events:
    """Replay the accumulator for one class (module docstring).

    gt, pred: the class's tracked boxes (`track` numbers the objects and hypotheses: one id per track);
    pair_*: (K,) the pairs of a ground-truth and a predicted box of the same sample closer than the threshold
    distance (the only ones that can match); thresholds: (R,) ascending score thresholds; positions: the most
    samples a scene has."""
    thresholds = np.asarray(thresholds, np.float64)
    runs, n_gt, n_pred = len(thresholds), len(gt), len(pred)
    status = np.zeros((runs, n_gt), np.int8)
    distance = np.full((runs, n_gt), np.nan)
    matched_pred = np.full((runs, n_gt), -1, np.int64)
    matched = np.zeros((runs, n_pred), bool)
    # a prediction is in the runs whose threshold it reaches: a prefix of the ascending thresholds
    passes = np.searchsorted(thresholds, pred.score, "right")
    active = np.arange(runs)[:, None] < passes[None, :]
    last_hyp = np.full((runs, int(gt.track.max(initial=-1)) + 1), -1, np.int64)  # motmetrics' `m`
    gt_order, gt_start = _by_position(gt, positions)
    pred_order, pred_start = _by_position(pred, positions)
    pair_order = np.argsort(gt.position[pair_gt], kind="stable")
    pair_start = np.searchsorted(gt.position[pair_gt][pair_order], np.arange(positions + 1), "left")
    solver_frames = 0
    for k in range(positions):
        q = pair_order[pair_start[k]:pair_start[k + 1]]
        if not len(q):
            continue
        # the pairs in every run that keeps their prediction: (run, gt row, pred row, distance)
        n_runs = passes[pair_pred[q]]
        run = np.arange(int(n_runs.sum())) - np.repeat(np.cumsum(n_runs) - n_runs, n_runs)
        g, p, d = np.repeat(pair_gt[q], n_runs), np.repeat(pair_pred[q], n_runs), np.repeat(pair_distance_m[q], n_runs)
        # 1. objects take back the hypothesis they last matched; of several, the first in the frame
        claim = np.flatnonzero(last_hyp[run, gt.track[g]] == pred.track[p])
        if len(claim):
            by_hyp = claim[np.lexsort((gt.order[g[claim]], p[claim], run[claim]))]
            first = np.r_[True, (run[by_hyp][1:] != run[by_hyp][:-1]) | (p[by_hyp][1:] != p[by_hyp][:-1])]
            won = by_hyp[first]
            status[run[won], g[won]] = MATCH
            distance[run[won], g[won]] = d[won]
            matched_pred[run[won], g[won]] = p[won]
            matched[run[won], p[won]] = True
        # 2. the rest: an assignment of the pairs left
        left = np.flatnonzero((status[run, g] == MISS) & ~matched[run, p])
        if not len(left):
            continue
        rl, gl, pl_ = run[left], g[left], p[left]
        _, g_inverse, g_count = np.unique(rl * n_gt + gl, return_inverse=True, return_counts=True)
        _, p_inverse, p_count = np.unique(rl * n_pred + pl_, return_inverse=True, return_counts=True)
        shared = (g_count[g_inverse.reshape(-1)] > 1) | (p_count[p_inverse.reshape(-1)] > 1)
        frame_key = rl * (int(gt.scene.max(initial=0)) + 1) + gt.scene[gl]
        hard_frames = np.unique(frame_key[shared])
        easy = ~np.isin(frame_key, hard_frames)
        take_run, take_g, take_p, take_d = [rl[easy]], [gl[easy]], [pl_[easy]], [d[left][easy]]
        if len(hard_frames):
            solver_frames += len(hard_frames)
            pairs = _solve_hard_frames(hard_frames, frame_key, rl, gl, pl_, d[left], gt, pred, gt_order,
                                       gt_start[k], gt_start[k + 1], pred_order, pred_start[k], pred_start[k + 1],
                                       active, status, matched)
            for part, values in zip((take_run, take_g, take_p, take_d), pairs):
                part.append(values)
        r2, g2, p2, d2 = (np.concatenate(part) for part in (take_run, take_g, take_p, take_d))
        previous = last_hyp[r2, gt.track[g2]]
        switch = (previous >= 0) & (previous != pred.track[p2])
        status[r2, g2] = np.where(switch, SWITCH, MATCH)
        distance[r2, g2] = d2
        matched_pred[r2, g2] = p2
        matched[r2, p2] = True
        last_hyp[r2, gt.track[g2]] = pred.track[p2]
    # objects matched in step 1 keep their hypothesis: `last_hyp` already holds it
    return Events(thresholds=thresholds, status=status, distance_m=distance, matched_pred=matched_pred,
                  active=active, matched=matched, solver_frames=solver_frames)


def _solve_hard_frames(frames, frame_key, run, g, p, d, gt, pred, gt_order, gt_lo, gt_hi, pred_order, pred_lo,
                       pred_hi, active, status, matched):
    """Step 2 of the frames in `frames` through `solve_frame`, each on its whole matrix as motmetrics builds it:
    every object and every active hypothesis of the frame in the frame's order, the step-1 pairs' rows and
    columns and the impossible pairs NaN. Returns (run, gt row, pred row, distance) of the pairs chosen."""
    num_scenes = int(gt.scene.max(initial=0)) + 1
    objects, hyps = gt_order[gt_lo:gt_hi], pred_order[pred_lo:pred_hi]  # sorted by (scene, order)
    object_scene, hyp_scene = gt.scene[objects], pred.scene[hyps]
    of_frame = np.argsort(frame_key, kind="stable")
    keys_sorted = frame_key[of_frame]
    out = [[], [], [], []]
    row_of = np.full(len(gt), -1, np.int64)
    col_of = np.full(len(pred), -1, np.int64)
    for key in frames.tolist():
        r, scene = divmod(key, num_scenes)
        rows = objects[slice(*np.searchsorted(object_scene, [scene, scene + 1]))]
        cols = hyps[slice(*np.searchsorted(hyp_scene, [scene, scene + 1]))]
        cols = cols[active[r, cols]]
        mine = of_frame[slice(*np.searchsorted(keys_sorted, [key, key + 1]))]
        row_of[rows] = np.arange(len(rows))
        col_of[cols] = np.arange(len(cols))
        costs = np.full((len(rows), len(cols)), np.nan)
        costs[row_of[g[mine]], col_of[p[mine]]] = d[mine]  # only pairs whose row and column are both left
        i, j = solve_frame(costs)
        out[0].append(np.full(len(i), r, np.int64))
        out[1].append(rows[i])
        out[2].append(cols[j])
        out[3].append(costs[i, j])
    return [np.concatenate(part) for part in out]
