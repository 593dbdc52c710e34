"""Panoptic segmentation and panoptic tracking evaluation from the Parquet: nuscenes-devkit's
`NuScenesPanopticEval` (PQ, SQ, RQ, mIoU, PQ-dagger; PAT, TQ, PTQ, sPTQ, LSTQ, MOTSA...), exactly.

```python
from nuparquet.evaluation.panoptic import evaluate_panoptic
result = evaluate_panoptic("OUT", "results/", "eval/", split="val", task="panoptic-tracking")
result.metrics["segmentation"]["all"]["PQ"], result.metrics["tracking"]["all"]["PAT"]
```

Settings are the one `EvalOptions` (tasks "panoptic" and "panoptic-tracking"; `nuparquet.evaluate(ds, results,
out, task=...)`). Modules, in the order the data flows: `submission` (the submission folder), `segments` (one
frame's instances and their intersections, counted once), `quality` (`PanopticEval`: PQ and the semantic IoU),
`tracking` (`PanopticTrackingEval`), `run` (the job). The class mapper is lidarseg's
(`evaluation.segmentation.classes`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["PanopticResult", "evaluate_panoptic"]

if TYPE_CHECKING:
    from nuparquet.evaluation.panoptic.run import PanopticResult, evaluate_panoptic

_HOMES = {"PanopticResult": "run", "evaluate_panoptic": "run"}


def __getattr__(name: str):
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(f"nuparquet.evaluation.panoptic.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'nuparquet.evaluation.panoptic' has no attribute {name!r}")
