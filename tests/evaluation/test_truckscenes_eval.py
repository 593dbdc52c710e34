"""`nuparquet eval` of a MAN TruckScenes output against truckscenes-devkit's DetectionEval (`detection_cvpr_2024`,
test-only) on generated TruckScenes data and seeded submissions made from its devkit's ground truth: the files
its `main` writes (metrics under "all", details keyed "all:<class>"), every number as docs/CONTRACTS.md says, and
the taxonomy's differences from nuScenes (twelve classes, traffic signs' orientation up to 180 degrees, the
errors each class leaves undefined, ranges from the LIDAR_LEFT keyframe, its own splits and attributes)."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import polars as pl
import pytest
from eval_reference import assert_same_metrics

from nuparquet.conversion import convert
from nuparquet.errors import InputError, UsageError
from nuparquet.evaluation import evaluate
from nuparquet.synth import synthesize

truckscenes = pytest.importorskip("truckscenes")
pytest.importorskip("pypcd4")
from pyquaternion import Quaternion  # noqa: E402
from truckscenes import TruckScenes  # noqa: E402
from truckscenes.eval.detection.config import config_factory  # noqa: E402
from truckscenes.eval.detection.evaluate import DetectionEval  # noqa: E402
from truckscenes.eval.detection.utils import category_to_detection_name, detection_name_to_rel_attributes  # noqa: E402
from truckscenes.utils.splits import create_splits_scenes  # noqa: E402

VERSION = "v1.2-mini"
SPLIT = "mini_val"
META = {"use_camera": False, "use_lidar": True, "use_radar": False, "use_map": False, "use_external": False}
# classes with no ground truth in the generated scenes, predicted as false positives
EXTRA_CLASSES = ("bus", "barrier", "traffic_cone", "bicycle", "motorcycle")


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return synthesize(tmp_path_factory.mktemp("ts-eval") / "root", scenes=2, samples_per_scene=6, seed=11,
                      family="truckscenes", version=VERSION)


@pytest.fixture(scope="module")
def out(root, tmp_path_factory):
    target = tmp_path_factory.mktemp("ts-eval-out") / "out"
    convert(root, VERSION, target)
    return target


@pytest.fixture(scope="module")
def ts(root):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return TruckScenes(VERSION, str(root), verbose=False)


def _split_samples(ts) -> list[dict]:
    scenes = set(create_splits_scenes()[SPLIT])
    return [s for s in ts.sample if ts.get("scene", s["scene_token"])["name"] in scenes]


def _submission(ts, seed: int | None) -> dict:
    """The devkit's ground truth as a submission: exact (seed None) or perturbed (seeded): boxes missed, moved,
    resized and turned (traffic signs often by half a turn), velocities off or NaN, attributes swapped, scores
    with ties, and false positives of classes without ground truth, beyond and within their ranges."""
    rng = np.random.default_rng(seed)
    attributes = {a["token"]: a["name"] for a in ts.attribute}
    results = {}
    for sample in _split_samples(ts):
        ego = ts.get("ego_pose", ts.get("sample_data", sample["data"]["LIDAR_LEFT"])["ego_pose_token"])["translation"]
        boxes = []
        for token in sample["anns"]:
            ann = ts.get("sample_annotation", token)
            name = category_to_detection_name(ann["category_name"])
            if name is None:
                continue
            translation, size = list(ann["translation"]), list(ann["size"])
            rotation, velocity = list(ann["rotation"]), [float(v) for v in ts.box_velocity(token)[:2]]
            attribute = attributes[ann["attribute_tokens"][0]] if ann["attribute_tokens"] else ""
            score = 1.0
            if seed is not None:
                if rng.random() < 0.15:
                    continue
                translation = [translation[0] + rng.normal(0, 0.6), translation[1] + rng.normal(0, 0.6),
                               translation[2] + rng.normal(0, 0.1)]
                size = [s * float(np.exp(rng.normal(0, 0.1))) for s in size]
                turn = rng.normal(0, 0.2) + (math.pi if name == "traffic_sign" and rng.random() < 0.5 else 0.0)
                rotation = list((Quaternion(rotation) * Quaternion(axis=[0, 0, 1], angle=turn)).elements)
                velocity = ([math.nan, math.nan] if rng.random() < 0.1 else
                            [v + rng.normal(0, 0.5) if math.isfinite(v) else 0.0 for v in velocity])
                relevant = detection_name_to_rel_attributes(name)
                if relevant and rng.random() < 0.3:
                    attribute = str(rng.choice(relevant))
                score = round(float(rng.uniform(0.1, 1.0)), 1)
            boxes.append({"sample_token": sample["token"], "translation": translation, "size": size,
                          "rotation": rotation, "velocity": velocity, "detection_name": name,
                          "detection_score": score, "attribute_name": attribute})
        if seed is not None:
            # a centimetre inside the range from LIDAR_LEFT's ego pose, ahead and behind: the other lidars'
            # keyframes (ms apart, the truck at 12 m/s) would put one of each pair out of range
            pose = ts.get("ego_pose", ts.get("sample_data", sample["data"]["LIDAR_LEFT"])["ego_pose_token"])
            heading = Quaternion(pose["rotation"]).rotation_matrix[:2, 0]
            for name, limit in (("pedestrian", 75.0), ("car", 150.0)):
                for sign in (1, -1):
                    xy = np.array(ego[:2]) + sign * (limit - 0.01) * heading
                    boxes.append({"sample_token": sample["token"], "translation": [float(xy[0]), float(xy[1]), 1.0],
                                  "size": [0.7, 0.7, 1.8], "rotation": [1.0, 0.0, 0.0, 0.0], "velocity": [0.0, 0.0],
                                  "detection_name": name, "detection_score": 0.95, "attribute_name": ""})
            for name in (*EXTRA_CLASSES, *rng.choice(["car", "pedestrian", "animal", "traffic_sign"], 3)):
                distance = rng.uniform(5, 160)
                angle = rng.uniform(-math.pi, math.pi)
                relevant = detection_name_to_rel_attributes(str(name))
                boxes.append({"sample_token": sample["token"],
                              "translation": [ego[0] + distance * math.cos(angle), ego[1] + distance * math.sin(angle),
                                              1.0],
                              "size": [1.5, 3.0, 1.5], "rotation": list(Quaternion(axis=[0, 0, 1], angle=angle).elements),
                              "velocity": [0.0, 0.0], "detection_name": str(name),
                              "detection_score": round(float(rng.uniform(0.1, 1.0)), 1),
                              "attribute_name": str(relevant[0]) if relevant else ""})
        results[sample["token"]] = boxes
    return {"meta": META, "results": results}


@pytest.fixture(scope="module")
def submissions(ts, tmp_path_factory):
    folder = tmp_path_factory.mktemp("ts-submissions")
    paths = {}
    for name, seed in (("perfect", None), ("noisy", 1), ("noisy2", 2)):
        paths[name] = folder / f"{name}.json"
        paths[name].write_text(json.dumps(_submission(ts, seed)))
    return paths


def _devkit(ts, results, out_dir, tags: bool = False) -> tuple[DetectionEval, dict, dict]:
    evaluation = DetectionEval(ts, config_factory("detection_cvpr_2024"), str(results), SPLIT, str(out_dir),
                               verbose=False)
    evaluation.main(render_curves=False, evaluate_tags=tags)
    return (evaluation, json.loads((out_dir / "metrics_summary.json").read_text()),
            json.loads((out_dir / "metrics_details.json").read_text()))


@pytest.mark.parametrize("name", ("perfect", "noisy", "noisy2"))
def test_metrics_equal_truckscenes_devkit(name, ts, out, submissions, tmp_path, capsys):
    _, summary, details = _devkit(ts, submissions[name], tmp_path / "devkit")
    # the TruckScenes configuration is the default for a TruckScenes dataset
    result = evaluate(out, results=submissions[name], split=SPLIT, out=tmp_path / "ours", plots=False)
    assert_same_metrics(tmp_path / "ours", summary, details)
    ours = json.loads((tmp_path / "ours" / "metrics_summary.json").read_text())
    assert list(ours) == ["all", "eval_time", "meta"] and ours["all"]["eval_time"] is None
    assert ours["eval_time"] > 0 and ours["all"]["cfg"] == config_factory("detection_cvpr_2024").serialize()
    assert list(json.loads((tmp_path / "ours" / "metrics_details.json").read_text())) == [
        f"all:{c}" for c in config_factory("detection_cvpr_2024").class_names]
    assert result.metrics.serialize()["nd_score"] == ours["all"]["nd_score"]


def test_the_noisy_submission_reaches_what_differs_from_nuscenes(ts, out, submissions, tmp_path, capsys):
    evaluation, summary, _ = _devkit(ts, submissions["noisy"], tmp_path / "devkit")
    metrics = summary["all"]
    gt_names = {box.detection_name for box in evaluation.gt_boxes.all}
    pred_names = {box.detection_name for box in evaluation.pred_boxes.all}
    # the TruckScenes classes with ground truth (the ego's own trailer is a trailer, vehicle.other other_vehicle)
    assert {"car", "truck", "pedestrian", "traffic_sign", "trailer", "animal", "other_vehicle"} <= gt_names
    assert set(EXTRA_CLASSES) <= pred_names - gt_names
    # half-turned traffic signs are matched with an orientation error below a quarter turn (period pi)
    assert 0 < metrics["label_tp_errors"]["traffic_sign"]["orient_err"] < math.pi / 4
    for name, undefined in (("traffic_sign", "vel_err"), ("animal", "attr_err"), ("traffic_cone", "orient_err"),
                            ("barrier", "vel_err")):
        assert math.isnan(metrics["label_tp_errors"][name][undefined]), (name, undefined)
    assert not math.isnan(metrics["label_tp_errors"]["traffic_sign"]["attr_err"])
    # boxes out to 150 m are evaluated for vehicles, to 75 m for the others
    kept = [(box.detection_name, box.ego_dist) for box in evaluation.pred_boxes.all]
    assert any(n == "car" and 75 < d < 150 for n, d in kept) or any(n == "bus" and 75 < d < 150 for n, d in kept)
    assert not any(n in ("pedestrian", "barrier", "traffic_cone", "animal") and d >= 75 for n, d in kept)
    ours = evaluate(out, results=submissions["noisy"], split=SPLIT)
    predictions = ours.predictions
    assert (predictions.filter(pl.col("filtered_by") == "range")["detection_name"].is_in(
        ["pedestrian", "barrier", "traffic_cone", "animal", "bicycle", "motorcycle", "traffic_sign", "car", "bus"])
        .all())
    assert predictions.filter(pl.col("evaluated")).height == len(evaluation.pred_boxes.all)


def test_ranges_are_measured_from_the_lidar_left_keyframe(out):
    # the generated lidars' keyframes are a few ms apart: their ego poses differ, LIDAR_LEFT's is the devkit's
    frames = pl.read_parquet(out / "frames").filter(pl.col("is_key_frame"))
    left = frames.filter(pl.col("channel").cast(pl.String) == "LIDAR_LEFT")
    top = frames.filter(pl.col("channel").cast(pl.String) == "LIDAR_TOP_FRONT")
    assert left["ego_translation"].to_list() != top["ego_translation"].to_list()


def test_the_scenes_take_truckscenes_split_names(out):
    scenes = pl.read_parquet(out / "scenes")
    assert scenes["name"].sort().to_list() == sorted(create_splits_scenes()[SPLIT])
    assert scenes["split"].to_list() == [SPLIT, SPLIT]


def test_the_nuscenes_configuration_is_refused_for_a_truckscenes_dataset(out, submissions):
    with pytest.raises(UsageError, match="nuscenes's detection classes.*truckscenes dataset.*detection_cvpr_2024"):
        evaluate(out, results=submissions["perfect"], split=SPLIT, config="detection_cvpr_2019")


def test_a_config_file_with_the_truckscenes_classes_is_read_as_truckscenes(out, submissions, tmp_path):
    content = config_factory("detection_cvpr_2024").serialize()
    content["class_range"] = {name: 40 for name in content["class_range"]}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(content))
    result = evaluate(out, results=submissions["noisy"], split=SPLIT, config_file=path)
    assert result.summary["all"]["cfg"]["class_range"]["car"] == 40
    reasons = result.predictions.filter(pl.col("filtered_by") == "range")
    assert reasons.height > 0 and (reasons["ego_distance_m"] >= 40).all()


def test_truckscenes_attributes_are_accepted_and_unknown_ones_named(ts, out, submissions, tmp_path):
    content = json.loads(submissions["perfect"].read_text())
    token, boxes = next((t, b) for t, b in content["results"].items() if b)
    boxes[0]["attribute_name"] = "traffic_sign.temporary"  # TruckScenes' own attribute
    path = tmp_path / "own.json"
    path.write_text(json.dumps(content))
    evaluate(out, results=path, split=SPLIT)
    boxes[0]["attribute_name"] = "vehicle.flying"
    path.write_text(json.dumps(content))
    with pytest.raises(InputError, match=f"sample {token} box 0: unknown attribute_name 'vehicle.flying'"):
        evaluate(out, results=path, split=SPLIT)


def test_per_tag_metrics_equal_the_devkits_evaluate_tags(ts, out, submissions, tmp_path, capsys):
    _, summary, details = _devkit(ts, submissions["noisy"], tmp_path / "devkit", tags=True)
    descriptions = [s["description"] for s in ts.scene]
    assert len(set(descriptions)) == 2 and any("weather.snow" in d for d in descriptions)  # tags differ by scene
    evaluate(out, results=submissions["noisy"], split=SPLIT, out=tmp_path / "ours", plots=False, tags=True)
    assert_same_metrics(tmp_path / "ours", summary, details)
    ours = json.loads((tmp_path / "ours" / "metrics_summary.json").read_text())
    # a tag of one scene only, a tag the devkit reports as NaN though a scene holds it, a tag no scene holds
    assert ours["weather.clear"]["mean_ap"] != ours["all"]["mean_ap"]
    assert math.isnan(ours["weather.snow"]["mean_ap"]) and ours["weather.snow"]["tp_scores"]["trans_err"] == 0.0
    assert ours["weather.fog"]["mean_ap"] == 0.0


def test_the_cli_prints_per_tag_results_and_tags_are_refused_where_there_are_none(out, submissions, tmp_path,
                                                                                    capsys, eval_out):
    from nuparquet.cli.main import main

    assert main(["eval", str(out), "--results", str(submissions["noisy"]), "--split", SPLIT, "--tags",
                 "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "Per-tag results:" in printed and "area.highway" in printed and "NDS:" in printed
    with pytest.raises(UsageError, match="--tags: the nuscenes benchmark has no scene tags"):
        evaluate(eval_out, results=submissions["noisy"], split="val", tags=True)
    with pytest.raises(UsageError, match="--tags applies to --task detection"):
        evaluate(out, results=submissions["noisy"], split=SPLIT, tags=True, task="tracking")
