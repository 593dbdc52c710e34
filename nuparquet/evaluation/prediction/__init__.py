"""Trajectory prediction evaluation from the Parquet: nuscenes-devkit's `compute_metrics` (MinADEK, MinFDEK,
MissRateTopK and OffRoadRate of the `predict_2020_icra` configuration), exactly.

```python
from nuparquet.evaluation.prediction import evaluate_prediction
result = evaluate_prediction("OUT", "predictions.json", "eval/", split="val")
result.metrics["MinFDEK"]["RowMean"], result.agents, result.modes  # the devkit's dict, per agent, per mode
```

Settings are the one `EvalOptions` (task "prediction"; `nuparquet.evaluate(ds, results, out, task="prediction")`).
Modules, in the order the data flows: `config` (the devkit's `PredictionConfig`), `submission` (the `Prediction`
records, as `Prediction.is_valid` checks them and more), `metrics` (displacements, the ranking by probability, the
min over the top k), `offroad` (the drivable-area test of `OffRoadRate`), `run` (the job; the futures come from
`frames.annotation_chains`, the devkit's `PredictHelper` walk).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["PredictionResult", "evaluate_prediction"]

if TYPE_CHECKING:
    from nuparquet.evaluation.prediction.run import PredictionResult, evaluate_prediction

_HOMES = {"PredictionResult": "run", "evaluate_prediction": "run"}


def __getattr__(name: str):
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(f"nuparquet.evaluation.prediction.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'nuparquet.evaluation.prediction' has no attribute {name!r}")
