"""Per-slice metrics against the devkit run on the correspondingly filtered inputs: its DetectionEval's filtered
ground truth and predictions, cut by the slice rule computed here from the devkit's own boxes and tables (the
ego distance it computed, the annotation's visibility and attribute, the scene's log and description, and for
predictions of ground-truth-only properties the box the devkit's matching loop gave them at 2 m)."""

from __future__ import annotations

import json
import re

import numpy as np
import polars as pl
import pytest
from eval_reference import (
    assert_same_metrics, devkit_eval, devkit_metrics_of, filtered, gt_box_tokens, sequential_matches,
)
from eval_submissions import ego_position, perfect, split_samples, write

from nuparquet.errors import UsageError
from nuparquet.evaluation import evaluate
from nuparquet.evaluation.classes import DETECTION_NAMES
from nuparquet.evaluation.run import slug

EVERY = object()


def _bins(value: float, edges, unit: str) -> str | None:
    if value < edges[0]:
        return None
    for low, high in zip(edges, edges[1:]):
        if low <= value < high:
            return f"{low:g}-{high:g}{unit}"
    return f"{edges[-1]:g}{unit}+"


@pytest.fixture(scope="module")
def sliced(submissions, eval_out, tmp_path_factory):
    """{by: (result, out)}: one evaluation with every named slice (distance in its default bins), one by a numeric
    annotation column in --bins."""
    folder = tmp_path_factory.mktemp("slices")
    by = ("distance", "visibility", "attribute", "location", "night", "rain", "scene", "vehicle")
    result = evaluate(eval_out, results=submissions["noisy"], split="val", out=folder / "named", plots=False, by=by)
    binned = evaluate(eval_out, results=submissions["noisy"], split="val", out=folder / "binned", plots=False,
                      by=("num_lidar_pts",), bins=("0", "5", "20"))
    return {**{name: (result, folder / "named") for name in by}, "num_lidar_pts": (binned, folder / "binned")}


def _devkit_reference(nusc, results, folder):
    """The devkit's evaluation of `results` (its filtered boxes), annotation tokens and its matches at 2 m."""
    evaluation = devkit_eval(nusc, results, folder)
    tokens = gt_box_tokens(nusc, evaluation.gt_boxes)
    matched = {}
    for name in DETECTION_NAMES:
        matched.update(sequential_matches(evaluation.gt_boxes, evaluation.pred_boxes, name, 2.0))
    meta = json.loads(open(evaluation.result_path).read())["meta"]
    return evaluation, tokens, matched, meta


@pytest.fixture(scope="module")
def reference(submissions, eval_nusc, tmp_path_factory):
    """The devkit's view of the noisy submission: `_devkit_reference`."""
    return _devkit_reference(eval_nusc, submissions["noisy"], tmp_path_factory.mktemp("devkit-slices"))


def _scene_of(nusc, sample_token: str) -> dict:
    return nusc.get("scene", nusc.get("sample", sample_token)["scene_token"])


def _scene_value(nusc, by: str, sample_token: str) -> str:
    scene = _scene_of(nusc, sample_token)
    log = nusc.get("log", scene["log_token"])
    if by == "location":
        return log["location"]
    if by == "night":
        return "night" if re.search(r"\bnight", scene["description"], re.I) else "day"
    if by == "rain":
        return "rain" if re.search(r"\brain", scene["description"], re.I) else "dry"
    if by == "scene":
        return scene["name"]
    return log[by]  # vehicle


def _gt_value(nusc, by: str, box, token: str):
    ann = nusc.get("sample_annotation", token)
    if by == "distance":
        return _bins(box.ego_dist, (0, 10, 20, 30, 40, 50), "m")
    if by == "visibility":
        return nusc.get("visibility", ann["visibility_token"])["level"]
    if by == "attribute":
        return box.attribute_name or "none"
    if by == "num_lidar_pts":
        return _bins(ann["num_lidar_pts"], (0, 5, 20), "")
    return _scene_value(nusc, by, box.sample_token)


def _pred_value(nusc, by: str, box, matched_gt, tokens):
    if by == "distance":
        return _bins(box.ego_dist, (0, 10, 20, 30, 40, 50), "m")
    if by in ("location", "night", "rain", "scene", "vehicle"):
        return _scene_value(nusc, by, box.sample_token)
    gt = matched_gt[id(box)]
    if gt is not None:
        return _gt_value(nusc, by, gt, tokens[id(gt)])
    return (box.attribute_name or "none") if by == "attribute" else EVERY


@pytest.mark.parametrize("by", ["distance", "visibility", "attribute", "location", "night", "rain", "scene",
                                "num_lidar_pts", "vehicle"])
def test_slice_metrics_equal_the_devkit_on_the_filtered_boxes(by, sliced, reference, eval_nusc):
    result, out = sliced[by]
    _assert_slices_equal_the_devkit(by, result, out, reference, eval_nusc)


def _assert_slices_equal_the_devkit(by, result, out, reference, eval_nusc) -> None:
    """Every slice of `by` (its labels, counts, metric files, mAP, NDS) against the devkit's `evaluate()` on the
    boxes the slice rule (computed here from the devkit's boxes and matches) puts in it."""
    evaluation, tokens, matched, meta = reference
    gt_values = {id(b): _gt_value(eval_nusc, by, b, tokens[id(b)]) for b in evaluation.gt_boxes.all}
    pred_values = {id(b): _pred_value(eval_nusc, by, b, matched, tokens) for b in evaluation.pred_boxes.all}
    labels = {v for v in list(gt_values.values()) + list(pred_values.values()) if v is not None and v is not EVERY}
    ours = result.slices.filter(pl.col("by") == by)
    assert set(ours["slice"]) == labels and len(labels) >= 1
    for label in labels:
        gt = filtered(evaluation.gt_boxes, lambda _, b: gt_values[id(b)] == label)
        pred = filtered(evaluation.pred_boxes, lambda _, b: pred_values[id(b)] in (label, EVERY))
        summary, details = devkit_metrics_of(evaluation, gt, pred, meta)
        assert_same_metrics(out / "slices" / slug(by) / slug(label), summary, details)
        row = ours.filter(pl.col("slice") == label).row(0, named=True)
        assert (row["num_gt"], row["num_predictions"]) == (len(gt.all), len(pred.all))
        assert row["mAP"] == summary["mean_ap"] and row["NDS"] == pytest.approx(summary["nd_score"], abs=1e-12)


def test_an_unmatched_prediction_counts_in_the_slice_of_its_own_attribute_only(eval_nusc, eval_out, tmp_path):
    """The ground-truth cars as predictions (score 0.5, their own attributes) and one false positive, a car predicted
    "vehicle.stopped" 20 m from the ego vehicle and far from every box, scored above them all: it lowers the car AP
    of the vehicle.stopped slice only (the devkit's evaluate() on the boxes filtered by attribute, the unmatched
    prediction by the attribute it predicted), not that of the moving, parked or attribute-less cars."""
    results = {token: [dict(box, detection_score=0.5) for box in boxes if box["detection_name"] == "car"]
               for token, boxes in perfect(eval_nusc).items()}
    sample = next(s for s in split_samples(eval_nusc) if results[s["token"]])
    ego = np.array(ego_position(eval_nusc, sample))
    centres = np.array([eval_nusc.get("sample_annotation", t)["translation"][:2] for t in sample["anns"]])
    spot = next(ego[:2] + 20.0 * np.array([np.cos(a), np.sin(a)]) for a in np.linspace(0, 2 * np.pi, 36)
                if np.linalg.norm(centres - (ego[:2] + 20.0 * np.array([np.cos(a), np.sin(a)])), axis=1).min() > 5.0)
    stray = dict(results[sample["token"]][0], translation=[*map(float, spot), float(ego[2]) + 0.8],
                 detection_score=0.9, attribute_name="vehicle.stopped")
    results[sample["token"]].append(stray)
    path = write(tmp_path / "results.json", results)
    result = evaluate(eval_out, results=path, split="val", out=tmp_path / "eval", plots=False, by=("attribute",))
    reference = _devkit_reference(eval_nusc, path, tmp_path / "devkit")

    evaluation, _, matched, _ = reference
    (kept,) = [b for b in evaluation.pred_boxes[sample["token"]] if b.detection_score == 0.9]
    assert matched[id(kept)] is None  # the case: evaluated, unmatched, with an attribute
    gt_attributes = {b.attribute_name or "none" for b in evaluation.gt_boxes.all if b.detection_name == "car"}
    assert {"vehicle.moving", "vehicle.parked", "vehicle.stopped"} <= gt_attributes
    _assert_slices_equal_the_devkit("attribute", result, tmp_path / "eval", reference, eval_nusc)
    # every prediction here counts in the slice of its own attribute (the matched ones matched a box with it)
    own = {}
    for box in evaluation.pred_boxes.all:
        own[box.attribute_name or "none"] = own.get(box.attribute_name or "none", 0) + 1
    counts = dict(result.slices.select("slice", "num_predictions").iter_rows())
    assert counts == {label: own.get(label, 0) for label in counts}
    cars = dict(result.slices.select("slice", "AP_car").iter_rows())
    assert cars["vehicle.stopped"] < min(cars["vehicle.moving"], cars["vehicle.parked"])


def test_slices_partition_the_ground_truth_and_charge_unmatched_predictions_everywhere(sliced):
    result, _ = sliced["distance"]
    evaluated_gt = result.ground_truth.filter(pl.col("evaluated")).height
    for by, group in result.slices.group_by("by"):
        if by[0] in ("distance", "location", "scene", "night", "rain", "vehicle", "visibility", "attribute"):
            assert group["num_gt"].sum() == evaluated_gt, by
    evaluated = result.predictions.filter(pl.col("evaluated"))
    unmatched = evaluated["matched_gt_2m"].null_count()
    visibility = result.slices.filter(pl.col("by") == "visibility")
    # every matched prediction in one slice, every unmatched one in all of them
    assert visibility["num_predictions"].sum() == evaluated.height - unmatched + unmatched * visibility.height
    scene = result.slices.filter(pl.col("by") == "scene")
    assert scene["num_predictions"].sum() == evaluated.height


def test_unknown_slices_and_bad_bins_are_refused(submissions, eval_out):
    with pytest.raises(UsageError, match="not a slice"):
        evaluate(eval_out, results=submissions["noisy"], by=("weather",))
    with pytest.raises(UsageError, match="--bins"):
        evaluate(eval_out, results=submissions["noisy"], by=("distance",), bins=("10", "5"))
    with pytest.raises(UsageError, match="distinct values"):
        evaluate(eval_out, results=submissions["noisy"], by=("num_lidar_pts",))


def test_slice_labels_follow_the_bins_in_order(sliced):
    distance = sliced["distance"][0].slices.filter(pl.col("by") == "distance")["slice"].to_list()
    assert distance == ["0-10m", "10-20m", "20-30m", "30-40m", "40-50m"]
    points = sliced["num_lidar_pts"][0].slices["slice"].to_list()
    assert points == ["0-5", "5-20", "20+"]


def test_a_slice_holding_only_predictions_is_listed():
    """A distance bin that no ground-truth box falls in but a prediction does (a false positive 25 m away) is a
    slice of its own: its predictions count against it (AP 0), so it is listed, in the bins' order; a prediction
    charged to every slice (EVERY_SLICE) names no slice, and nor does a box before the first edge (None)."""
    from nuparquet.evaluation.slices import EVERY_SLICE, dimension

    common = {"gt_annotations": pl.DataFrame(), "gt_attribute": np.array([], object),
              "pred_attribute": np.array([], object), "gt_sample": np.zeros(2, np.int64),
              "pred_sample": np.zeros(3, np.int64), "sample_scene": pl.DataFrame(),
              "pred_matched_gt": np.array([0, -1, -1])}
    distance = dimension("distance", gt_ego_distance_m=np.array([5.0, 3.0]),
                         pred_ego_distance_m=np.array([5.5, 25.0, 2.0]), bins=None, **common)
    assert distance.labels == ("0-10m", "20-30m")
    later = dimension("distance", gt_ego_distance_m=np.array([15.0, 15.0]),
                      pred_ego_distance_m=np.array([15.0, 12.0, 4.0]), bins=(10.0, 20.0, 30.0), **common)
    assert later.labels == ("10-20m",) and later.pred_label[2] is None  # 4 m is before the first edge
    gt_annotations = pl.DataFrame({"vehicle": ["van", "van"]})
    vehicle = dimension("vehicle", gt_ego_distance_m=np.zeros(2), pred_ego_distance_m=np.zeros(3),
                        bins=None, **{**common, "gt_annotations": gt_annotations})
    assert vehicle.labels == ("van",) and vehicle.pred_label.tolist() == ["van", EVERY_SLICE, EVERY_SLICE]
