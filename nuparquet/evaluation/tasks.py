"""The benchmarks `nuparquet eval --task` evaluates, one package each, reached through the one verb
(`evaluation.run.evaluate`): task name -> its function `(dataset, results, out, options: EvalOptions, *, on_progress)`.
Detection is `evaluation.run` itself."""

from __future__ import annotations

import importlib

TASKS = {
    "tracking": "nuparquet.evaluation.tracking.run:evaluate_tracking",
    "lidarseg": "nuparquet.evaluation.segmentation.run:evaluate_lidarseg",
    "panoptic": "nuparquet.evaluation.panoptic.run:evaluate_panoptic",
    "panoptic-tracking": "nuparquet.evaluation.panoptic.run:evaluate_panoptic",
    "prediction": "nuparquet.evaluation.prediction.run:evaluate_prediction",
}


def task_function(task: str):
    """The evaluation function of `task` (imported on first use: a task's package loads only when asked for)."""
    module, name = TASKS[task].split(":")
    return getattr(importlib.import_module(module), name)
