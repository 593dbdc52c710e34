"""The reference side of the evaluation tests: nuscenes-devkit's DetectionEval run on the same dataroot and
submission, a literal transcription of its matching loop (to learn which ground truth each prediction took),
and the comparison of two metric JSON files."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np

from nuscenes.eval.common.data_classes import EvalBoxes
from nuscenes.eval.common.utils import center_distance
from nuscenes.eval.detection.config import config_factory
from nuscenes.eval.detection.data_classes import DetectionConfig
from nuscenes.eval.detection.evaluate import DetectionEval

TOLERANCE = 1e-12  # relative (absolute below 1): docs/CONTRACTS.md, "What equal to the devkit means"
# Only the orientation error (and what averages it) may differ, by rounding: pyquaternion's rotation matrix comes
# from a BLAS 4x4 product (its kernel chosen by the CPU), ours from the same terms summed in numpy. The centre
# distance and the velocity error go through the same BLAS dot as the devkit's np.linalg.norm: bit-equal.
INEXACT_ALLOWED = ("orient_err", "nd_score", "tp_scores")


def devkit_config(config_file: Path | None = None) -> DetectionConfig:
    if config_file is None:
        return config_factory("detection_cvpr_2019")
    return DetectionConfig.deserialize(json.loads(Path(config_file).read_text()))


def devkit_eval(nusc, results: Path, out_dir: Path, split: str = "val", config_file: Path | None = None
                ) -> DetectionEval:
    """An initialised DetectionEval (submission and ground truth loaded and filtered)."""
    return DetectionEval(nusc, devkit_config(config_file), str(results), split, str(out_dir), verbose=False)


def devkit_metrics(evaluation: DetectionEval) -> tuple[dict, dict]:
    """(metrics_summary, metrics_details) as DetectionEval.main writes them (read back from its files)."""
    evaluation.main(render_curves=False)
    out = Path(evaluation.output_dir)
    return (json.loads((out / "metrics_summary.json").read_text()),
            json.loads((out / "metrics_details.json").read_text()))


def devkit_metrics_of(evaluation: DetectionEval, gt_boxes: EvalBoxes, pred_boxes: EvalBoxes, meta: dict
                      ) -> tuple[dict, dict]:
    """The devkit's metrics of an initialised evaluation run on other (filtered) boxes: its `evaluate()`,
    serialized as `main` does, through JSON (NaN and key types as in the files)."""
    evaluation = copy.copy(evaluation)
    evaluation.gt_boxes, evaluation.pred_boxes = gt_boxes, pred_boxes
    metrics, data = evaluation.evaluate()
    summary = metrics.serialize()
    summary["meta"] = dict(meta)
    return json.loads(json.dumps(summary)), json.loads(json.dumps(data.serialize()))


def compare(ours, theirs, path: str = "", inexact: list | None = None) -> list:
    """Assert equal structure (keys in order) and values: floats within TOLERANCE relative (absolute below 1; NaN
    equals NaN; eval_time not compared), everything else exactly. Returns the paths whose floats differ at all."""
    inexact = [] if inexact is None else inexact
    if isinstance(theirs, dict):
        assert isinstance(ours, dict) and list(ours) == list(theirs), f"{path}: keys {list(ours)} != {list(theirs)}"
        for key in theirs:
            compare(ours[key], theirs[key], f"{path}/{key}", inexact)
    elif isinstance(theirs, list):
        assert isinstance(ours, list) and len(ours) == len(theirs), f"{path}: lengths differ"
        for i, (a, b) in enumerate(zip(ours, theirs)):
            compare(a, b, f"{path}[{i}]", inexact)
    elif isinstance(theirs, float) and not path.endswith("eval_time"):
        assert isinstance(ours, (int, float)), f"{path}: {ours!r} is not a number"
        if math.isnan(theirs):
            assert math.isnan(ours), f"{path}: {ours} != NaN"
        elif ours != theirs:
            assert abs(ours - theirs) <= TOLERANCE * max(1.0, abs(theirs)), f"{path}: {ours} != {theirs}"
            inexact.append(path)
    elif not path.endswith("eval_time"):
        assert ours == theirs and type(ours) is type(theirs), f"{path}: {ours!r} != {theirs!r}"
    return inexact


def assert_same_metrics(ours_dir: Path, summary: dict, details: dict) -> None:
    """Our metrics_summary.json / metrics_details.json against the devkit's: every number equal within 1e-12
    relative, and bit-equal except where the orientation error enters (on every machine: docs/CONTRACTS.md)."""
    ours_summary = json.loads((Path(ours_dir) / "metrics_summary.json").read_text())
    ours_details = json.loads((Path(ours_dir) / "metrics_details.json").read_text())
    inexact = compare(ours_summary, summary, "summary") + compare(ours_details, details, "details")
    unexpected = [p for p in inexact if not any(name in p for name in INEXACT_ALLOWED)]
    assert not unexpected, f"values not bit-equal outside the orientation error: {unexpected[:5]}"


def sequential_matches(gt_boxes: EvalBoxes, pred_boxes: EvalBoxes, class_name: str, dist_th: float) -> dict:
    """The devkit's `accumulate` matching loop, transcribed: {id(prediction box): ground-truth box or None} for
    the predictions of `class_name` (an independent expectation for our vectorised matching)."""
    pred_list = [box for box in pred_boxes.all if box.detection_name == class_name]
    confs = [box.detection_score for box in pred_list]
    sortind = [i for (v, i) in sorted((v, i) for (i, v) in enumerate(confs))][::-1]
    taken = set()
    result = {}
    for ind in sortind:
        pred = pred_list[ind]
        min_dist, match = np.inf, None
        for gt_idx, gt in enumerate(gt_boxes[pred.sample_token]):
            if gt.detection_name == class_name and (pred.sample_token, gt_idx) not in taken:
                distance = center_distance(gt, pred)
                if distance < min_dist:
                    min_dist, match = distance, gt_idx
        if min_dist < dist_th:
            taken.add((pred.sample_token, match))
            result[id(pred)] = gt_boxes[pred.sample_token][match]
        else:
            result[id(pred)] = None
    return result


def filtered(boxes: EvalBoxes, keep) -> EvalBoxes:
    """`boxes` with only those for which keep(sample_token, box) holds (every sample kept, in order)."""
    out = EvalBoxes()
    for token in boxes.sample_tokens:
        out.add_boxes(token, [box for box in boxes[token] if keep(token, box)])
    return out


def gt_box_tokens(nusc, gt_boxes: EvalBoxes) -> dict:
    """{id(ground-truth box): sample_annotation token}: a sample's boxes are its detection-class annotations in
    `anns` order, less the filtered ones, so they are found in order by position and size."""
    from nuscenes.eval.detection.utils import category_to_detection_name

    tokens = {}
    for sample_token in gt_boxes.sample_tokens:
        candidates = [nusc.get("sample_annotation", t) for t in nusc.get("sample", sample_token)["anns"]]
        candidates = iter(a for a in candidates if category_to_detection_name(a["category_name"]) is not None)
        for box in gt_boxes[sample_token]:
            ann = next(a for a in candidates if tuple(a["translation"]) == tuple(box.translation)
                       and tuple(a["size"]) == tuple(box.size))
            tokens[id(box)] = ann["token"]
    return tokens


def pred_box_keys(results_path: Path, pred_boxes: EvalBoxes) -> dict:
    """{id(prediction box): (sample_token, position in the sample's list of the submission)}."""
    results = json.loads(Path(results_path).read_text())["results"]
    keys = {}
    for sample_token in pred_boxes.sample_tokens:
        listed = iter(enumerate(results[sample_token]))
        for box in pred_boxes[sample_token]:
            index = next(i for i, b in listed if tuple(b["translation"]) == tuple(box.translation)
                         and b["detection_score"] == box.detection_score and b["detection_name"] == box.detection_name)
            keys[id(box)] = (sample_token, index)
    return keys
