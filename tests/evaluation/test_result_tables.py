"""predictions/ and ground_truth/: which boxes were evaluated and which ground truth each prediction took at each
threshold, against the devkit's filtered boxes and its matching loop (transcribed in `eval_reference`)."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from eval_reference import devkit_eval, gt_box_tokens, pred_box_keys, sequential_matches
from eval_submissions import ego_position

from nuparquet.evaluation import evaluate
from nuparquet.evaluation.classes import DETECTION_NAMES
from nuparquet.evaluation.tables import threshold_suffix

THRESHOLDS = (0.5, 1.0, 2.0, 4.0)


@pytest.mark.parametrize("name", ["noisy", "edges"])
def test_matches_and_filters_equal_the_devkit(name, submissions, eval_out, eval_nusc, tmp_path):
    evaluation = devkit_eval(eval_nusc, submissions[name], tmp_path / "devkit")
    result = evaluate(eval_out, results=submissions[name], split="val")
    gt_token = gt_box_tokens(eval_nusc, evaluation.gt_boxes)
    pred_key = pred_box_keys(submissions[name], evaluation.pred_boxes)
    predictions = result.predictions.filter(pl.col("evaluated"))
    assert set(zip(predictions["sample_token"], predictions["box_index"])) == set(pred_key.values())
    assert set(result.ground_truth.filter(pl.col("evaluated"))["token"]) == set(gt_token.values())
    assert result.predictions.filter(~pl.col("evaluated"))["filtered_by"].null_count() == 0
    matched_somewhere = 0
    for threshold in THRESHOLDS:
        expected = {}
        for class_name in DETECTION_NAMES:
            for box_id, gt in sequential_matches(evaluation.gt_boxes, evaluation.pred_boxes, class_name,
                                                 threshold).items():
                expected[pred_key[box_id]] = None if gt is None else gt_token[id(gt)]
        suffix = threshold_suffix(threshold)
        keys = zip(predictions["sample_token"], predictions["box_index"])
        ours = dict(zip(keys, predictions[f"matched_gt_{suffix}"]))
        assert ours == expected
        matched_somewhere += sum(v is not None for v in expected.values())
        # the ground-truth side says the same, from the other end
        gt_rows = result.ground_truth.filter(pl.col(f"matched_box_{suffix}").is_not_null())
        taken = zip(gt_rows["sample_token"], gt_rows[f"matched_box_{suffix}"], gt_rows["token"])
        assert {(s, b): t for s, b, t in taken} == {k: v for k, v in expected.items() if v is not None}
    assert matched_somewhere > 0


def test_tables_describe_each_box(submissions, eval_out, eval_nusc, tmp_path):
    result = evaluate(eval_out, results=submissions["edges"], split="val", out=tmp_path / "out", plots=False)
    predictions = pl.read_parquet(tmp_path / "out" / "predictions")
    assert predictions.equals(result.predictions)
    # the edge submission has boxes beyond a class range, claiming no points, and cycles in racks
    assert set(predictions["filtered_by"].drop_nulls()) == {"range", "points", "bike_rack"}
    assert (predictions["evaluated"] == predictions["filtered_by"].is_null()).all()
    left_out = predictions.filter(~pl.col("evaluated"))
    assert left_out["rank"].null_count() == left_out.height
    # rank: 0.. within each class, by descending score, ties to the box later in the submission
    evaluated = predictions.filter(pl.col("evaluated")).with_row_index("position")
    for _, group in evaluated.group_by("detection_name"):
        ordered = group.sort("rank")
        assert ordered["rank"].to_list() == list(range(group.height))
        assert ordered["detection_score"].to_list() == sorted(ordered["detection_score"], reverse=True)
        ties = ordered.filter(pl.col("detection_score").is_duplicated())
        for _, tied in ties.group_by("detection_score"):
            assert tied.sort("rank")["position"].to_list() == sorted(tied["position"], reverse=True)
    # TP errors at 2 m exactly for the true positives at 2 m; the translation error is the match distance
    tp = predictions.filter(pl.col("matched_gt_2m").is_not_null())
    fp = predictions.filter(pl.col("matched_gt_2m").is_null())
    assert tp.height and fp.height
    assert all(fp[name].null_count() == fp.height for name in ("trans_err", "scale_err", "orient_err", "attr_err"))
    assert (tp["trans_err"] == tp["match_distance_m_2m"]).all() and tp["scale_err"].null_count() == 0
    gt = pl.read_parquet(tmp_path / "out" / "ground_truth")
    assert gt.equals(result.ground_truth)
    assert set(gt["filtered_by"].drop_nulls()) == {"range", "points", "bike_rack"}
    # the columns of the module docstring, in its order
    assert gt.columns == ["token", "sample_token", "scene_name", "timestamp", "detection_name", "attribute_name",
                          "visibility_name", "num_pts", "ego_distance_m", "evaluated", "filtered_by",
                          *[f"{kind}_{threshold_suffix(t)}" for t in THRESHOLDS
                            for kind in ("matched_box", "match_distance_m")]]
    # ego_distance_m: the devkit's ego_dist, from the annotation to its sample's LIDAR_TOP ego pose, in the plane
    for name, table, key in (("ground truth", gt, "token"), ("predictions", predictions, None)):
        expected = []
        for row in table.iter_rows(named=True):
            ego = np.array(ego_position(eval_nusc, eval_nusc.get("sample", row["sample_token"])))
            where = (np.array(eval_nusc.get("sample_annotation", row[key])["translation"]) if key
                     else np.array(row["translation"]))
            expected.append(np.sqrt(np.sum((where[:2] - ego[:2]) ** 2)))
        np.testing.assert_allclose(table["ego_distance_m"].to_numpy(), expected, rtol=1e-12, err_msg=name)
