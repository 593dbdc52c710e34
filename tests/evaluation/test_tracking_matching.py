"""The tracking evaluation's pieces against their references, on random inputs full of ties: the accumulator
against motmetrics 1.4.0's `MOTAccumulator` itself (the devkit's `MOTAccumulatorCustom` is its subclass), the
interpolation against the devkit's `interpolate_tracks`, the track means against `np.mean`."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest

from nuparquet.evaluation.tracking.accumulator import MATCH, MISS, SWITCH, accumulate, solve_frame
from nuparquet.evaluation.tracking.tracks import Timeline, TrackedBoxes, build_tracks, pairwise_mean
from nuparquet.geometry.cuboids import Cuboids


def _random_scenes(rng, scenes=6, frames=9):
    """Frames of objects and hypotheses with distances from a grid of few values (equal costs), NaN for pairs that
    cannot match; ids recur over frames (tracks), appear, vanish and come back."""
    data = []
    for _ in range(scenes):
        frames_of_scene = []
        for _ in range(frames):
            objects = sorted(rng.choice(8, size=int(rng.integers(0, 6)), replace=False).tolist())
            hyps = sorted(rng.choice(9, size=int(rng.integers(0, 7)), replace=False).tolist())
            rng.shuffle(objects)
            rng.shuffle(hyps)
            d = rng.choice([0.5, 1.0, 1.0, 1.5, np.nan, np.nan], size=(len(objects), len(hyps)))
            frames_of_scene.append((objects, hyps, d))
        data.append(frames_of_scene)
    return data


def _ours(data):
    """The same frames through `accumulate` (one run, every hypothesis kept)."""
    gt, pred, pairs = defaultdict(list), defaultdict(list), []
    for s, frames in enumerate(data):
        for k, (objects, hyps, d) in enumerate(frames):
            g0, p0 = len(gt["scene"]), len(pred["scene"])
            for i, o in enumerate(objects):
                gt["scene"].append(s), gt["position"].append(k), gt["track"].append(s * 100 + o), gt["order"].append(i)
            for j, h in enumerate(hyps):
                pred["scene"].append(s), pred["position"].append(k), pred["track"].append(s * 100 + h)
                pred["order"].append(j)
            for i, j in zip(*np.nonzero(np.isfinite(d))):
                pairs.append((g0 + i, p0 + j, d[i, j]))

    def boxes(cols):
        n = len(cols["scene"])
        return TrackedBoxes(cuboids=Cuboids.empty() if not n else Cuboids(np.zeros((n, 3)), np.ones((n, 3)),
                                                                          np.tile([1.0, 0, 0, 0], (n, 1))),
                            sample=np.array(cols["scene"]) * 100 + np.array(cols["position"]),
                            scene=np.array(cols["scene"]), position=np.array(cols["position"]),
                            track=np.array(cols["track"]), class_index=np.zeros(n, np.int64),
                            score=np.ones(n), source=np.arange(n), order=np.array(cols["order"]))

    g, p, d = (np.array([x[i] for x in pairs]) for i in range(3))
    events = accumulate(boxes(gt), boxes(pred), g.astype(np.int64), p.astype(np.int64), d.astype(float),
                        np.array([-np.inf]), positions=max(len(f) for f in data))
    return events


@pytest.mark.parametrize("seed", range(4))
def test_the_accumulator_gives_motmetrics_events(seed):
    import motmetrics
    rng = np.random.default_rng(seed)
    data = _random_scenes(rng)
    events = _ours(data)
    expected_status, expected_hyp_matched = [], []
    for frames in data:
        acc = motmetrics.MOTAccumulator()
        for k, (objects, hyps, d) in enumerate(frames):
            acc.update(objects, hyps, d, frameid=k)
        table = acc.events.reset_index()
        for k, (objects, hyps, _) in enumerate(frames):
            mine = table[(table.FrameId == k) & table.Type.isin(["MATCH", "SWITCH", "MISS", "FP"])]
            kind = {float(o): t for o, t in zip(mine.OId, mine.Type) if t != "FP"}
            expected_status += [{"MATCH": MATCH, "SWITCH": SWITCH, "MISS": MISS}[kind[float(o)]] for o in objects]
            matched_h = {float(h) for h, t in zip(mine.HId, mine.Type) if t in ("MATCH", "SWITCH")}
            expected_hyp_matched += [float(h) in matched_h for h in hyps]
    assert events.status[0].tolist() == expected_status
    assert events.matched[0].tolist() == expected_hyp_matched
    assert (events.status[0] == SWITCH).any() and events.solver_frames > 0  # the cases the test is for


def test_the_frame_solver_is_motmetrics_lap_with_scipy():
    from motmetrics.lap import linear_sum_assignment as motmetrics_lsa

    rng = np.random.default_rng(7)
    for _ in range(200):
        costs = rng.choice([0.5, 1.0, 1.0, np.nan], size=(int(rng.integers(1, 6)), int(rng.integers(1, 6))))
        rows, cols = solve_frame(costs)
        expected_rows, expected_cols = motmetrics_lsa(costs, solver="scipy")
        assert rows.tolist() == list(expected_rows) and cols.tolist() == list(expected_cols)


def test_track_means_are_np_mean_bit_for_bit():
    rng = np.random.default_rng(3)
    counts = np.r_[rng.integers(1, 8, 40), rng.integers(8, 129, 40), rng.integers(129, 400, 5)]
    group = np.repeat(np.arange(len(counts)), counts)
    values = rng.random(len(group)) * rng.choice([1.0, 1e-3, 1e5], len(group))
    shuffle = np.argsort(rng.random(len(group)))
    values, group = values[shuffle], group[shuffle]
    expected = np.array([np.mean(values[group == i]) for i in range(len(counts))])
    assert pairwise_mean(values, group, len(counts)).tolist() == expected.tolist()


def test_interpolation_is_the_devkits_box_for_box():
    """Tracks with gaps of 1 to 3 samples (the devkit's right_ratio gives the right box the left box's weight),
    uneven timestamps, a track changing class: translations, scores, classes and the order in each sample."""
    from nuscenes.eval.common.config import config_factory
    from nuscenes.eval.tracking.data_classes import TrackingBox
    from nuscenes.eval.tracking.loaders import interpolate_tracks

    config_factory("tracking_nips_2019")  # sets the devkit's TRACKING_NAMES
    rng = np.random.default_rng(5)
    positions = 12
    timestamps = np.cumsum(rng.integers(400_000, 600_000, positions)) + 1_500_000_000_000_000
    rows = []  # (position, track id, class, x, y, score)
    for track in range(7):
        present = np.sort(rng.choice(positions, size=int(rng.integers(2, 8)), replace=False))
        for p in present:
            rows.append((int(p), f"t{track}", "car" if (track != 3 or p < 6) else "truck",
                         float(rng.normal(1000, 30)), float(rng.normal(1600, 30)), float(rng.choice([0.3, 0.7]))))
    rng.shuffle(rows)
    rows.sort(key=lambda r: r[0])  # by sample, listed in a random order within it
    devkit = defaultdict(list)
    for t in timestamps.tolist():
        devkit[t] = []
    for p, tid, name, x, y, score in rows:
        devkit[int(timestamps[p])].append(TrackingBox(translation=(x, y, 0.5), size=(1, 2, 1), rotation=(1, 0, 0, 0),
                                                      tracking_id=tid, tracking_name=name, tracking_score=score))
    devkit = interpolate_tracks(devkit)
    n = len(rows)
    sample = np.array([r[0] for r in rows])
    timeline = Timeline.of(np.zeros(positions, np.int64), timestamps, 1)
    cuboids = Cuboids(np.array([[r[3], r[4], 0.5] for r in rows]), np.tile([1.0, 2, 1], (n, 1)),
                      np.tile([1.0, 0, 0, 0], (n, 1)))
    classes = {"car": 0, "truck": 1}
    ours = build_tracks(cuboids, sample, np.array([r[1] for r in rows], object),
                        np.array([classes[r[2]] for r in rows]), np.array([r[5] for r in rows]), timeline,
                        average_scores=False)
    assert (ours.source < 0).any()
    track_ids = {}
    for p in range(positions):
        mine = np.flatnonzero(ours.sample == p)
        mine = mine[np.argsort(ours.order[mine])]
        theirs = devkit[int(timestamps[p])]
        assert len(mine) == len(theirs)
        for row, box in zip(mine.tolist(), theirs):
            assert ours.translation_m[row, :2].tolist() == list(box.translation[:2])
            assert ours.score[row] == box.tracking_score
            assert ours.class_index[row] == classes[box.tracking_name]
            assert track_ids.setdefault(int(ours.track[row]), box.tracking_id) == box.tracking_id


def test_a_tracks_first_box_is_its_earliest_in_time_then_in_sample_order():
    """The tracks tables name each track by its first box (scene, class, tracking_id): the box of the smallest
    position, ties by the order in the sample, whatever the rows' order (a class that changes along a track
    shows its first class)."""
    from types import SimpleNamespace

    from nuparquet.evaluation.tracking.tables import _first_box_per_track

    tracks = SimpleNamespace(track=np.array([1, 0, 1, 0, 2, 1]), position=np.array([2, 1, 0, 3, 5, 0]),
                             order=np.array([0, 0, 1, 0, 0, 0]))
    # track 0: rows 1 (position 1), 3 (3) -> row 1; track 1: rows 0 (2), 2 (0, order 1), 5 (0, order 0) -> row 5
    assert _first_box_per_track(tracks, 4).tolist() == [1, 5, 4, -1]  # track 3 has no box: -1
    empty = SimpleNamespace(track=np.zeros(0, np.int64), position=np.zeros(0, np.int64), order=np.zeros(0, np.int64))
    assert _first_box_per_track(empty, 0).tolist() == []


def test_each_kept_prediction_names_the_ground_truth_it_matched_and_minus_one_otherwise():
    """`slicing.matched_ground_truth`: with every prediction kept, a prediction matched to a real (not interpolated)
    ground-truth box gets that box's kept row; unmatched ones, and matches of interpolated boxes, get -1."""
    from types import SimpleNamespace

    from nuparquet.evaluation.tracking.slicing import matched_ground_truth

    inputs = SimpleNamespace(pred_kept=np.arange(4))
    gt_tracks = SimpleNamespace(source=np.array([0, 1, -1]))  # row 2 is an interpolated box
    pred_tracks = SimpleNamespace(source=np.array([3, 0, 2, -1]))
    car = SimpleNamespace(every=SimpleNamespace(matched_pred=np.array([[1, -1, 3]])), gt_rows=np.array([0, 1, 2]),
                          pred_rows=np.array([0, 1, 2, 3]))
    unevaluated = SimpleNamespace(every=None, gt_rows=np.zeros(0, np.int64), pred_rows=np.zeros(0, np.int64))
    evaluation = SimpleNamespace(classes={"car": car, "bus": unevaluated})
    out = matched_ground_truth(inputs, evaluation, gt_tracks, pred_tracks)
    # gt row 0 matched pred row 1 (source 0); gt row 2 (interpolated) matched pred row 3: no slice of its own
    assert out.dtype == np.int64 and out.tolist() == [0, -1, -1, -1]
