"""metrics_summary.json and metrics_details.json against nuscenes-devkit's DetectionEval on the same dataroot and
submission: every key in the devkit's order, every number equal within 1e-9 and bit-equal except where the
orientation error enters, for every class (those without ground truth or without predictions included)."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from eval_reference import assert_same_metrics, devkit_eval, devkit_metrics

from nuparquet.evaluation import evaluate

CASES = ("perfect", "noisy", "noisy2", "edges")


@pytest.mark.parametrize("name", CASES)
def test_metrics_equal_the_devkit(name, submissions, eval_out, eval_nusc, tmp_path):
    summary, details = devkit_metrics(devkit_eval(eval_nusc, submissions[name], tmp_path / "devkit"))
    evaluate(eval_out, results=submissions[name], split="val", out=tmp_path / "ours", plots=False)
    assert_same_metrics(tmp_path / "ours", summary, details)


def test_a_perfect_submission_matches_every_evaluated_box_at_distance_zero(submissions, eval_out):
    result = evaluate(eval_out, results=submissions["perfect"], split="val")
    gt = result.ground_truth.filter(pl.col("evaluated"))
    # (at larger thresholds a prediction whose own box was filtered out may take a neighbour's box first)
    assert gt["matched_box_0_5m"].null_count() == 0
    assert (gt["match_distance_m_0_5m"] == 0).all()
    # its only false positives: the boxes of annotations without points, which the devkit drops from the ground
    # truth but not from the predictions (they claim no point count)
    false_positives = result.predictions.filter(pl.col("evaluated") & pl.col("matched_gt_0_5m").is_null())
    pointless = result.ground_truth.filter(pl.col("filtered_by") == "points")
    assert false_positives.height == pointless.height > 0
    assert set(false_positives["sample_token"]) == set(pointless["sample_token"])
    assert result.summary["mean_dist_aps"]["pedestrian"] > result.summary["mean_dist_aps"]["trailer"] == 0.0


def test_the_noisy_submissions_reach_classes_without_ground_truth_or_predictions(submissions, eval_nusc, tmp_path):
    evaluation = devkit_eval(eval_nusc, submissions["noisy"], tmp_path)
    gt_names = {box.detection_name for box in evaluation.gt_boxes.all}
    pred_names = {box.detection_name for box in evaluation.pred_boxes.all}
    assert {"trailer", "construction_vehicle"} & pred_names - gt_names  # predictions, no ground truth
    assert "bus" in gt_names - pred_names  # ground truth, no prediction
    velocities = np.array([box.velocity for box in evaluation.pred_boxes.all])
    assert np.isnan(velocities).any() and (~np.isnan(velocities)).any()
    scores = [box.detection_score for box in evaluation.pred_boxes.all]
    assert len(set(scores)) < len(scores) / 5  # many ties in score


def test_the_edge_submission_reaches_the_exact_boundaries(submissions, eval_nusc, eval_edits, edge_placement,
                                                          eval_out, tmp_path):
    from nuscenes.eval.common.utils import center_distance

    evaluation = devkit_eval(eval_nusc, submissions["edges"], tmp_path)
    # predictions exactly at each matching threshold from their ground truth survive the filters
    gt_by_sample = evaluation.gt_boxes
    at = {t: 0 for t in (0.5, 1.0, 2.0, 4.0)}
    for pred in evaluation.pred_boxes.all:
        for gt in gt_by_sample[pred.sample_token]:
            d = center_distance(gt, pred)
            if d in at and gt.detection_name == pred.detection_name:
                at[d] += 1
    assert all(n > 0 for n in at.values()), at
    # at exactly a class range from the ego: left out; a hair inside: kept (predictions and ground truth)
    kept = [(box.detection_name, box.ego_dist) for box in evaluation.pred_boxes.all]
    for name, limit in (("car", 50.0), ("pedestrian", 40.0), ("barrier", 30.0)):
        assert (name, limit) not in kept and any(n == name and limit - 1e-9 < d < limit for n, d in kept), name
    kept_gt = {(tuple(b.translation)) for b in evaluation.gt_boxes.all}
    for token, inside in eval_edits["at_range"]:
        assert (tuple(eval_nusc.get("sample_annotation", token)["translation"]) in kept_gt) == inside
    # cycles in a rack are left out (ground truth and predictions), the one 5 cm outside is kept
    for token in eval_edits["in_rack"]:
        assert tuple(eval_nusc.get("sample_annotation", token)["translation"]) not in kept_gt
    for token in eval_edits["outside_rack"]:
        assert tuple(eval_nusc.get("sample_annotation", token)["translation"]) in kept_gt
    # the two boxes at one spot: the JSON lists them in the other order than their instance tokens sort
    annotations = pl.read_parquet(eval_out / "annotations")
    flipped = 0
    for new, old in eval_edits["duplicates"]:
        rows = annotations.filter(pl.col("token").is_in([new, old]))["token"].to_list()
        flipped += rows == [old, new]  # stored order (scene, time, instance) puts the car first, JSON the copy
    assert 0 < flipped < len(eval_edits["duplicates"])
    assert edge_placement["on_duplicates"] and edge_placement["in_rack"]
    assert len(eval_edits["in_rack"]) >= 2 and len(eval_edits["outside_rack"]) == 3


def test_tp_errors_above_one_score_zero_and_nds_follows_the_devkit():
    """A mean TP error above 1 (a 1.7 m translation error is common for a weak detector) scores 0, not -0.7: the
    devkit clips each TP score to [0, 1] before NDS. Our DetectionMetrics against the devkit's on the same table."""
    from nuscenes.eval.detection.config import config_factory
    from nuscenes.eval.detection.data_classes import DetectionMetrics as DevkitMetrics

    from nuparquet.evaluation.config import named_config
    from nuparquet.evaluation.metrics import TP_METRICS, DetectionMetrics

    config = named_config("detection_cvpr_2019")
    theirs = DevkitMetrics(config_factory("detection_cvpr_2019"))
    label_aps, label_tp_errors = {}, {}
    for i, name in enumerate(config.class_names):
        label_aps[name] = {th: 0.1 * (i % 7) + 0.01 * k for k, th in enumerate(config.dist_ths)}
        label_tp_errors[name] = {metric: 1.7 if metric == "trans_err" else 0.2 + 0.05 * j
                                 for j, metric in enumerate(TP_METRICS)}
        for th, ap in label_aps[name].items():
            theirs.add_label_ap(name, th, ap)
        for metric, error in label_tp_errors[name].items():
            theirs.add_label_tp(name, metric, error)
    ours = DetectionMetrics(config, label_aps, label_tp_errors)
    assert ours.tp_scores["trans_err"] == theirs.tp_scores["trans_err"] == 0.0
    assert ours.tp_scores == pytest.approx(theirs.tp_scores, abs=1e-12)
    assert ours.nd_score == pytest.approx(theirs.nd_score, abs=1e-12)
