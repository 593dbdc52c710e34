"""The vectorised greedy matching against the devkit's loop written out plainly (random scenes with many ties in
score and in distance), and its pieces: the processing order and the chunked candidate search."""

from __future__ import annotations

import numpy as np
import pytest

from nuparquet.evaluation import matching
from nuparquet.evaluation.boxes import Boxes
from nuparquet.geometry.cuboids import Cuboids


def _boxes(rng, n, samples, classes, *, grid: float, score=None) -> Boxes:
    xy = np.round(rng.uniform(0, 6, (n, 2)) / grid) * grid  # on a grid: equal distances happen
    return Boxes(cuboids=Cuboids(np.c_[xy, np.zeros(n)], np.ones((n, 3)), np.tile([1.0, 0, 0, 0], (n, 1))),
                 sample_index=rng.integers(0, samples, n), class_index=rng.integers(0, classes, n),
                 velocity_mps=np.zeros((n, 2)), attribute=np.full(n, "", object),
                 score=np.round(rng.uniform(0, 1, n), 1) if score is None else score, num_pts=np.full(n, -1))


def _plain_loop(gt: Boxes, pred: Boxes, threshold: float) -> np.ndarray:
    """The devkit's accumulate loop per class: predictions by sorted((score, i))[::-1], each taking the nearest
    untaken box of its sample and class (first listed on ties) if closer than the threshold."""
    match = np.full(len(pred), -1)
    for c in np.unique(pred.class_index):
        rows = np.flatnonzero(pred.class_index == c)
        order = [i for (_, i) in sorted((pred.score[r], k) for k, r in enumerate(rows))][::-1]
        taken = set()
        for k in order:
            p = rows[k]
            best, best_d = None, np.inf
            for g in np.flatnonzero((gt.sample_index == pred.sample_index[p]) & (gt.class_index == c)):
                d = np.linalg.norm(pred.translation_m[p, :2] - gt.translation_m[g, :2])
                if g not in taken and d < best_d:
                    best, best_d = g, d
            if best_d < threshold:
                taken.add(best)
                match[p] = best
    return match


@pytest.mark.parametrize("seed", range(12))
def test_greedy_matching_equals_the_sequential_loop(seed):
    rng = np.random.default_rng(seed)
    gt = _boxes(rng, 60, samples=4, classes=2, grid=0.5)
    pred = _boxes(rng, 90, samples=4, classes=2, grid=0.25)
    thresholds = (0.5, 1.0, 2.0, 4.0)
    result = matching.match_boxes(gt, pred, thresholds, num_classes=2)
    ties = 0
    for t, threshold in enumerate(thresholds):
        expected = _plain_loop(gt, pred, threshold)
        np.testing.assert_array_equal(result.gt[t], expected)
        hit = expected >= 0
        offsets = pred.translation_m[hit, :2] - gt.translation_m[expected[hit], :2]
        np.testing.assert_array_equal(result.distance_m[t, hit], np.linalg.norm(offsets, axis=1))
        assert np.isnan(result.distance_m[t, ~hit]).all()
        ties += hit.sum()
    assert ties > 0


def test_processing_order_is_descending_score_then_the_later_box():
    pred = _boxes(np.random.default_rng(0), 6, samples=1, classes=1, grid=1.0,
                  score=np.array([0.5, 0.9, 0.5, 0.1, 0.9, 0.5]))
    assert matching.processing_order(pred).tolist() == [4, 1, 5, 2, 0, 3]


def test_chunked_candidate_search_finds_the_same_pairs(monkeypatch):
    rng = np.random.default_rng(3)
    gt = _boxes(rng, 200, samples=5, classes=3, grid=0.1)
    pred = _boxes(rng, 300, samples=5, classes=3, grid=0.1)
    whole = matching.candidate_pairs(gt, pred, 4.0, 3)
    monkeypatch.setattr(matching, "PAIRS_PER_CHUNK", 7)
    chunked = matching.candidate_pairs(gt, pred, 4.0, 3)
    for a, b in zip(whole, chunked):
        np.testing.assert_array_equal(a, b)
    p, g, d = whole
    assert (gt.sample_index[g] == pred.sample_index[p]).all() and (gt.class_index[g] == pred.class_index[p]).all()
    assert (d < 4.0).all() and len(p) > 100


def test_no_ground_truth_or_no_prediction_matches_nothing():
    rng = np.random.default_rng(1)
    gt = _boxes(rng, 5, samples=2, classes=2, grid=1.0)
    result = matching.match_boxes(gt, Boxes.empty(), (1.0, 2.0), 2)
    assert result.gt.shape == (2, 0)
    result = matching.match_boxes(Boxes.empty(), gt, (1.0, 2.0), 2)
    assert (result.gt == -1).all() and np.isnan(result.distance_m).all()


def test_no_boxes_have_each_field_in_its_documented_dtype_and_shape():
    """`Boxes.empty()`: zero rows of every field as the class documents it (int64 indices, float64 values, str
    attributes), so its indices index the class names as any boxes' do (numpy refuses a float index array)."""
    empty = Boxes.empty()
    documented = {"sample_index": (np.int64, ()), "class_index": (np.int64, ()), "translation_m": (np.float64, (3,)),
                  "size_wlh_m": (np.float64, (3,)), "rotation_wxyz": (np.float64, (4,)),
                  "velocity_mps": (np.float64, (2,)), "attribute": (object, ()), "score": (np.float64, ()),
                  "num_pts": (np.int64, ())}
    for name, (dtype, shape) in documented.items():
        value = getattr(empty, name)
        assert value.dtype == np.dtype(dtype) and value.shape == (0, *shape), name
    assert len(empty) == 0 and np.array(["car", "truck"])[empty.class_index].shape == (0,)


def test_candidate_search_finds_every_pair_closer_than_the_distance():
    """The x-window search against all pairs measured: coordinates far from the origin and negative, boxes exactly
    at the distance in x (not taken: strictly closer), several samples and classes."""
    rng = np.random.default_rng(5)
    gt = _boxes(rng, 300, samples=6, classes=3, grid=0.5)
    pred = _boxes(rng, 400, samples=6, classes=3, grid=0.5)
    gt.translation_m[:, 0] -= 1800.0
    pred.translation_m[:, 0] -= 1800.0
    p, g, d = matching.candidate_pairs(gt, pred, 2.0, 3)
    found = set(zip(p.tolist(), g.tolist()))
    expected = set()
    for i in range(len(pred)):
        for j in range(len(gt)):
            same = pred.sample_index[i] == gt.sample_index[j] and pred.class_index[i] == gt.class_index[j]
            if same and np.linalg.norm(pred.translation_m[i, :2] - gt.translation_m[j, :2]) < 2.0:
                expected.add((i, j))
    assert found == expected and len(expected) > 50
    exactly_at = [(i, j) for i in range(len(pred)) for j in range(len(gt))
                  if pred.sample_index[i] == gt.sample_index[j] and pred.class_index[i] == gt.class_index[j]
                  and np.linalg.norm(pred.translation_m[i, :2] - gt.translation_m[j, :2]) == 2.0]
    assert exactly_at and not set(exactly_at) & found  # the grid puts pairs exactly at the distance: left out
    np.testing.assert_array_equal(d, np.linalg.norm(pred.translation_m[p, :2] - gt.translation_m[g, :2], axis=1))
