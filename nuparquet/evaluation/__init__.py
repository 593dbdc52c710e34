"""Detection evaluation from the Parquet: nuscenes-devkit's `DetectionEval` (mAP, the five TP errors, NDS),
exactly, from a converted dataset, with the predictions as data and the metrics per slice.

```python
from nuparquet.evaluation import evaluate
result = evaluate("OUT", results="results.json", split="val", out="eval/", by=("distance", "night"))
result.summary["nd_score"]                 # metrics_summary.json, the devkit's keys and values
result.predictions                         # one row per predicted box: matched ground truth at each threshold
result.slices                              # one row per slice: counts, mAP, TP errors, NDS, AP per class
```

Modules, in the order the data flows: `options` (the settings and CLI flags), `config` (the devkit's
configurations), `submission` (reading and checking results.json), `splits`, `ground_truth` (from the
datasets), `filters` (class ranges, points, bike racks), `matching` (greedy centre-distance matching),
`metrics` (curves, AP, TP errors, NDS), `slices`, `tables` (predictions/ and ground_truth/), `plots`, `run`.
The heavy modules load on first use: the CLI builds its parser from `options` alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["DetectionConfig", "EvalOptions", "EvalResult", "evaluate"]

if TYPE_CHECKING:
    from nuparquet.evaluation.config import DetectionConfig
    from nuparquet.evaluation.options import EvalOptions
    from nuparquet.evaluation.run import EvalResult, evaluate

_HOMES = {"DetectionConfig": "config", "EvalOptions": "options", "EvalResult": "run", "evaluate": "run"}


def __getattr__(name: str):
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(f"nuparquet.evaluation.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'nuparquet.evaluation' has no attribute {name!r}")
