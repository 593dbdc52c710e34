"""Boxes into tracks, as the devkit's `create_tracks` does for the ground truth and the predictions alike: the
evaluated (filtered) boxes of every scene of the split laid out on the scene's samples, a predicted track's
boxes given the mean score of the track, and the gaps of every track filled in.

- Samples of a scene are taken in time order (the devkit walks `first_sample_token` -> `next`, keyed by timestamp).
- A track is a (scene, tracking id) pair: the instance token of a ground-truth box, the submission's tracking_id
  (the same id in two scenes is two tracks). A track may change class; it is one track still.
- Score: every box of a predicted track gets the mean of the track's scores (before interpolation), computed as
  `np.mean` sums them (`pairwise_mean`: numpy's pairwise summation, in the order the devkit lists them: by sample,
  then as listed in the sample), because a threshold equal to a score must select the same boxes.
- Interpolation (`interpolate_tracks`): every sample between two boxes of a track that has none of it gets one,
  with the devkit's weight `right_ratio = (t_right - t) / (t_right - t_left)` given to the *right* box (so a box
  two samples before the right one sits nearer the right one: the devkit's arithmetic, kept), the score
  interpolated the same way, the class and id of the right box. Interpolated boxes come after the sample's own
  boxes, in the order the tracks first appear in the scene (the devkit appends them in that order; the order
  decides the accumulator's ties).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from nuparquet.geometry.cuboids import CuboidRows, Cuboids

PW_BLOCKSIZE = 128  # numpy's pairwise summation: blocks summed with 8 accumulators up to this length


@dataclass(frozen=True)
class Timeline:
    """The evaluated samples laid out by scene. scene: (S,) scene index of each sample; position: (S,) its place
    in its scene's time order; scene_start: (C + 1,) offsets of each scene's samples in `by_position`;
    by_position: (S,) sample indices ordered by (scene, position)."""

    scene: np.ndarray
    position: np.ndarray
    scene_start: np.ndarray
    by_position: np.ndarray
    timestamp_us: np.ndarray

    @classmethod
    def of(cls, scene_index: np.ndarray, timestamp_us: np.ndarray, num_scenes: int) -> Timeline:
        order = np.lexsort((timestamp_us, scene_index))
        counts = np.bincount(scene_index, minlength=num_scenes)
        start = np.r_[0, np.cumsum(counts)]
        position = np.empty(len(order), np.int64)
        position[order] = np.arange(len(order)) - start[scene_index[order]]
        return cls(scene=scene_index, position=position, scene_start=start, by_position=order,
                   timestamp_us=timestamp_us)

    def sample_at(self, scene: np.ndarray, position: np.ndarray) -> np.ndarray:
        return self.by_position[self.scene_start[scene] + position]

    @property
    def max_positions(self) -> int:
        return int(np.diff(self.scene_start).max()) if len(self.scene_start) > 1 else 0


@dataclass(frozen=True)
class TrackedBoxes(CuboidRows):
    """Boxes of tracks, the evaluated ones and the interpolated ones, one row each.

    sample: (N,) sample index; scene, position: (N,) its scene and place in it; track: (N,) int64 track index
    (one per (scene, tracking id), numbered by first appearance); class_index: (N,) into the configuration's
    classes; score: (N,) the score the devkit thresholds (the track's mean; -1 for ground truth); source: (N,)
    the row of the evaluated boxes it is, -1 when interpolated; order: (N,) its rank among the boxes of its sample
    (the devkit's list order)."""

    sample: np.ndarray
    scene: np.ndarray
    position: np.ndarray
    track: np.ndarray
    class_index: np.ndarray
    score: np.ndarray
    source: np.ndarray
    order: np.ndarray


def pairwise_mean(values: np.ndarray, group: np.ndarray, num_groups: int) -> np.ndarray:
    """(num_groups,) the mean of each group's values as `np.mean` of the group's values in the given order gives
    it, bit for bit: numpy's pairwise sum (a plain loop below 8 values, 8 interleaved accumulators up to 128,
    halves above), divided by the count. `group`: (N,) group of each value, values of a group in their order.
    Vectorised over the groups: the loops run over positions in a group (at most 128), not over groups."""
    counts = np.bincount(group, minlength=num_groups)
    order = np.argsort(group, kind="stable")
    starts = np.r_[0, np.cumsum(counts)[:-1]].astype(np.int64)
    v, g = values[order], group[order]
    j = np.arange(len(order)) - starts[g]  # place within the group
    sums = np.zeros(num_groups)
    n = counts[g]
    short, blocked = n < 8, (n >= 8) & (n <= PW_BLOCKSIZE)
    for k in range(int(counts[counts < 8].max(initial=0))):  # res = 0.; res += v, for each v in turn
        at = short & (j == k)
        sums[g[at]] += v[at]
    if blocked.any():
        lanes = np.zeros((num_groups, 8))
        full = n - n % 8
        head = blocked & (j < 8)
        lanes[g[head], j[head]] = v[head]
        for block in range(1, PW_BLOCKSIZE // 8):
            at = blocked & (j >= 8 * block) & (j < 8 * block + 8) & (j < full)
            if not at.any():
                break
            lanes[g[at], j[at] - 8 * block] += v[at]
        mine = np.flatnonzero((counts >= 8) & (counts <= PW_BLOCKSIZE))
        r = lanes[mine]
        sums[mine] = ((r[:, 0] + r[:, 1]) + (r[:, 2] + r[:, 3])) + ((r[:, 4] + r[:, 5]) + (r[:, 6] + r[:, 7]))
        for k in range(7):  # the rest, below a multiple of 8, added in turn
            at = blocked & (j == full + k)
            sums[g[at]] += v[at]
    for i in np.flatnonzero(counts > PW_BLOCKSIZE):  # tracks of more than 128 boxes: rare, summed by halves
        sums[i] = _pairwise_sum(values[order[starts[i]:starts[i] + counts[i]]])
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums / counts


def _pairwise_sum(a: np.ndarray) -> float:
    n = len(a)
    if n < 8:
        res = 0.0
        for v in a.tolist():
            res += v
        return res
    if n <= PW_BLOCKSIZE:
        full = n - n % 8
        r = a[:8].copy()
        for i in range(8, full, 8):
            r += a[i:i + 8]
        res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
        for v in a[full:].tolist():
            res += v
        return float(res)
    half = n // 2
    half -= half % 8
    return _pairwise_sum(a[:half]) + _pairwise_sum(a[half:])


def build_tracks(cuboids: Cuboids, sample: np.ndarray, track_key: np.ndarray, class_index: np.ndarray,
                 score: np.ndarray, timeline: Timeline, *, average_scores: bool) -> TrackedBoxes:
    """The tracks of the evaluated boxes (rows in the devkit's order: by sample, then as listed), with their gaps
    interpolated (module docstring). track_key: (N,) the tracking id (str); average_scores: give each box its
    track's mean score (the predictions)."""
    n = len(sample)
    scene, position = timeline.scene[sample], timeline.position[sample]
    # one track per (scene, key), numbered by first appearance in (scene, position, row) order
    walk = np.lexsort((np.arange(n), position, scene))
    _, key_code = np.unique(np.asarray(track_key, dtype=object).astype(str), return_inverse=True)
    keys = scene.astype(np.int64) * (int(key_code.max(initial=0)) + 1) + key_code.reshape(-1)
    _, first_row, inverse = np.unique(keys[walk], return_index=True, return_inverse=True)
    appearance = np.empty(len(first_row), np.int64)
    appearance[np.argsort(first_row, kind="stable")] = np.arange(len(first_row))
    track = np.empty(n, np.int64)
    track[walk] = appearance[inverse.reshape(-1)]
    num_tracks = len(first_row)
    if average_scores and n:
        score = pairwise_mean(score[walk], track[walk], num_tracks)[track]
    boxes = TrackedBoxes(cuboids=cuboids, sample=sample, scene=scene, position=position, track=track,
                         class_index=class_index, score=np.asarray(score, np.float64), source=np.arange(n),
                         order=_rank_in_sample(sample, n))
    return interpolate_tracks(boxes, timeline)


def _rank_in_sample(sample: np.ndarray, n: int) -> np.ndarray:
    order = np.argsort(sample, kind="stable")
    counts = np.bincount(sample) if n else np.zeros(0, np.int64)
    rank = np.empty(n, np.int64)
    rank[order] = np.arange(n) - np.repeat(np.cumsum(counts) - counts, counts)
    return rank


def interpolate_tracks(boxes: TrackedBoxes, timeline: Timeline) -> TrackedBoxes:
    """`boxes` with a box added in every sample a track skips between two of its boxes (module docstring)."""
    by_track = np.lexsort((boxes.position, boxes.track))
    same = boxes.track[by_track][1:] == boxes.track[by_track][:-1]
    left, right = by_track[:-1][same], by_track[1:][same]
    gap = boxes.position[right] - boxes.position[left] - 1
    left, right, gap = left[gap > 0], right[gap > 0], gap[gap > 0]
    if not len(gap):
        return boxes
    pair = np.repeat(np.arange(len(gap)), gap)
    step = np.arange(int(gap.sum())) - np.repeat(np.cumsum(gap) - gap, gap) + 1
    lo, hi = left[pair], right[pair]
    position = boxes.position[lo] + step
    scene = boxes.scene[hi]
    sample = timeline.sample_at(scene, position)
    t, t_left, t_right = (timeline.timestamp_us[sample], timeline.timestamp_us[boxes.sample[lo]],
                          timeline.timestamp_us[boxes.sample[hi]])
    right_ratio = (t_right - t).astype(np.float64) / (t_right - t_left).astype(np.float64)
    w_left, w_right = 1.0 - right_ratio, right_ratio
    translation = w_left[:, None] * boxes.translation_m[lo] + w_right[:, None] * boxes.translation_m[hi]
    size = w_left[:, None] * boxes.size_wlh_m[lo] + w_right[:, None] * boxes.size_wlh_m[hi]
    score = w_left * boxes.score[lo] + w_right * boxes.score[hi]
    # the rotation is the right box's: the devkit slerps it, but nothing it evaluates reads it
    added = TrackedBoxes(
        cuboids=Cuboids(translation, size, boxes.rotation_wxyz[hi], boxes.cuboids.at), sample=sample, scene=scene,
        position=position, track=boxes.track[hi], class_index=boxes.class_index[hi], score=score,
        source=np.full(len(pair), -1, np.int64), order=np.zeros(len(pair), np.int64))
    # after the sample's own boxes, in the order the tracks first appear in the scene (track numbers)
    within = np.lexsort((added.track, added.sample))
    counts_own = np.bincount(boxes.sample, minlength=len(timeline.scene))
    rank = np.empty(len(pair), np.int64)
    s_sorted = added.sample[within]
    first = np.searchsorted(s_sorted, s_sorted, "left")
    rank[within] = counts_own[s_sorted] + np.arange(len(pair)) - first
    added = dataclasses.replace(added, order=rank)
    return TrackedBoxes(
        cuboids=Cuboids.concat([boxes.cuboids, added.cuboids]),
        **{f: np.concatenate([getattr(boxes, f), getattr(added, f)]) for f in
           ("sample", "scene", "position", "track", "class_index", "score", "source", "order")})
