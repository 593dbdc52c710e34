"""Lidar segmentation evaluation from the Parquet: nuscenes-devkit's `LidarSegEval` (per-class IoU over the 16
challenge classes, mIoU, frequency-weighted IoU; index 0 ignored), exactly.

```python
from nuparquet.evaluation.segmentation import evaluate_lidarseg
result = evaluate_lidarseg("OUT", "results/", "eval/", split="val")
result.metrics["miou"], result.confusion            # the devkit's result dict, the (17, 17) confusion matrix
```

Settings are the one `EvalOptions` (task "lidarseg"; `nuparquet.evaluate(ds, results, out, task="lidarseg")`).
Modules, in the order the data flows: `classes` (the devkit's `LidarsegClassMapper`), `submission` (the
submission folder, as `validate_submission` checks it), `confusion` (the devkit's `ConfusionMatrix` arithmetic and
result dict), `run` (the job).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["LidarsegResult", "evaluate_lidarseg"]

if TYPE_CHECKING:
    from nuparquet.evaluation.segmentation.run import LidarsegResult, evaluate_lidarseg

_HOMES = {"LidarsegResult": "run", "evaluate_lidarseg": "run"}


def __getattr__(name: str):
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(f"nuparquet.evaluation.segmentation.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'nuparquet.evaluation.segmentation' has no attribute {name!r}")
