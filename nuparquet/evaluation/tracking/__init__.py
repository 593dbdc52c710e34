"""Tracking evaluation from the Parquet: nuscenes-devkit's `TrackingEval` (AMOTA, AMOTP, MOTA, MOTP, IDS, FRAG, TID,
LGD... with motmetrics 1.4.0's matching), exactly, without motmetrics or pandas.

```python
from nuparquet.evaluation.tracking import evaluate_tracking
result = evaluate_tracking("OUT", "tracking_results.json", "eval/", split="val")
result.summary["amota"]                    # metrics_summary.json, the devkit's keys and values
result.tracks                              # one row per ground-truth track: matched, switches, missed
```

Settings are the one `EvalOptions` (task "tracking"; `nuparquet.evaluate(ds, results, out, task="tracking")`).
Modules, in the order the data flows: `config` (the devkit's configurations), `run` (submission,
ground truth and filters: the detection evaluation's, generalised), `tracks` (score means and interpolation),
`accumulator` (motmetrics' matching), `metrics` (thresholds, per-threshold metrics, metric data, summary),
`scoring` (one evaluation, class by class), `slicing`, `tables`, `plots`, `output`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["TrackingConfig", "TrackingResult", "evaluate_tracking"]

if TYPE_CHECKING:
    from nuparquet.evaluation.tracking.config import TrackingConfig
    from nuparquet.evaluation.tracking.run import TrackingResult, evaluate_tracking

_HOMES = {"TrackingConfig": "config", "TrackingResult": "run",
          "evaluate_tracking": "run"}


def __getattr__(name: str):
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(f"nuparquet.evaluation.tracking.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'nuparquet.evaluation.tracking' has no attribute {name!r}")
