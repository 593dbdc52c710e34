"""Training straight from the Parquet, without torch: `Samples` (one split as a map-style dataset with
mmdetection3d v1.4.0's semantics), its scene shards and resumable seeded stream, and `collate`.

```python
from nuparquet.training import Samples
samples = Samples("OUT", "train", sweeps=10)
item = samples[0]          # {"points": (P, 5) float32, "gt_bboxes_3d": (N, 9) float32, "img": (6, H, W, 3), ...}
```

Modules: `samples` (`Samples`: the fields, built from `nuparquet.index`'s arrays), `shards` (scene shards, the
seeded stream, worker split, resume state), `collate` (batches).
"""

from __future__ import annotations

# numpy only, and imported here so that `nuparquet.training.collate` is the function (not its module)
from nuparquet.training.collate import collate

__all__ = ["SampleStream", "Samples", "collate", "worker_init_fn"]


def __getattr__(name: str):
    # Samples pulls in polars and the index: loaded on first use
    if name == "Samples":
        from nuparquet.training.samples import Samples

        return Samples
    if name in ("SampleStream", "worker_init_fn"):
        from nuparquet.training import shards

        return getattr(shards, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
