"""Per-scene-tag detection metrics, as truckscenes-devkit's `DetectionEval.evaluate(evaluate_tags=True)` computes
them (`eval --tags`), and the tagged files its `main` writes.

A scene's tags are its `description` split at ";". The devkit masks the samples of scenes without the tag out of
both the ground truth and the predictions (`get_scene_tag_masks`, `accumulate`'s masks), which is the evaluation of
the samples of scenes with it; every tag of the taxonomy is evaluated, with or without samples (a tag no scene
holds gives the "no predictions" curves). For the tags the devkit deems too rare (`Taxonomy.unevaluated_tags`),
every AP and TP error is NaN while the curves stay computed.

Files: metrics_summary.json is {"all": metrics, <tag>: metrics, ..., "eval_time": seconds, "meta": ...} (each
tag's own eval_time None); metrics_details.json is {"<tag>:<class>": curves at the class's last threshold}
(`metrics.serialize_details(..., tag=)`, the devkit's key collision kept).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from nuparquet.evaluation.boxes import Boxes
from nuparquet.evaluation.classes import TP_METRICS
from nuparquet.evaluation.config import DetectionConfig
from nuparquet.evaluation.metrics import DetectionMetrics, serialize_details


def sample_tags(descriptions, tags) -> np.ndarray:
    """(S, T) bool: sample s's scene description (";"-separated) holds tag t."""
    held = [set(str(d).split(";")) for d in descriptions]
    return np.array([[tag in h for tag in tags] for h in held], dtype=bool).reshape(len(held), len(tags))


def tag_evaluations(gt_boxes: Boxes, pred_boxes: Boxes, sample_descriptions, config: DetectionConfig,
                    evaluate_boxes: Callable) -> dict:
    """{tag: evaluation} for every tag of the configuration's taxonomy, in its order: `evaluate_boxes` (the
    detection evaluation) of the boxes of samples whose scene holds the tag, NaN metrics for unevaluated tags.
    sample_descriptions: (S,) the scene description of each evaluated sample."""
    taxonomy = config.taxonomy
    holds = sample_tags(sample_descriptions, taxonomy.scene_tags)
    result = {}
    for t, tag in enumerate(taxonomy.scene_tags):
        gt_rows = np.flatnonzero(holds[gt_boxes.sample_index, t]) if len(gt_boxes) else np.zeros(0, np.int64)
        pred_rows = np.flatnonzero(holds[pred_boxes.sample_index, t]) if len(pred_boxes) else np.zeros(0, np.int64)
        evaluation = evaluate_boxes(gt_boxes.take(gt_rows), pred_boxes.take(pred_rows), config)
        if tag in taxonomy.unevaluated_tags:
            nan_aps = {name: {threshold: np.nan for threshold in config.dist_ths} for name in config.class_names}
            nan_errors = {name: dict.fromkeys(TP_METRICS, np.nan) for name in config.class_names}
            evaluation = replace(evaluation, metrics=DetectionMetrics(config, nan_aps, nan_errors,
                                                                      evaluation.metrics.eval_time))
        result[tag] = evaluation
    return result


def tagged_summary(evaluations: dict, meta: dict) -> dict:
    """metrics_summary.json of the devkit's `DetectionMetricsList`: {tag: metrics} ("all" first), the evaluation
    time summed over the tags, the submission's meta."""
    summary = {tag: DetectionMetrics(e.metrics.config, e.metrics.label_aps, e.metrics.label_tp_errors).serialize()
               for tag, e in evaluations.items()}
    return {**summary, "eval_time": sum(e.metrics.eval_time or 0.0 for e in evaluations.values()), "meta": dict(meta)}


def tagged_details(evaluations: dict) -> dict:
    """metrics_details.json of the devkit's `DetectionMetricDataList` over the tags."""
    details = {}
    for tag, evaluation in evaluations.items():
        details.update(serialize_details(evaluation.data, tag=tag))
    return details
