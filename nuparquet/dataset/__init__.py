"""Open a converted nuparquet directory and query it lazily with polars.

```python
import nuparquet
ds = nuparquet.open("OUT")                        # reads OUT/manifest.json only
lf = ds.scan("annotations")                       # polars.LazyFrame: nothing read until .collect()
ds.sql('SELECT channel, COUNT(*) AS n FROM frames GROUP BY channel')   # polars.DataFrame
ds.boxes(token)                                   # get_sample_data's boxes, for one frame or many
ds.map("boston-seaport").layers_on_point(x, y)    # the map expansion
```

`path` is a local directory or any URL polars can scan (``s3://bucket/out``, ``gs://…``, ``az://…``,
``https://…``, ``hf://…``); `storage_options` (polars' vocabulary) reach the manifest and every dataset
(`storage`). Modules: `core` (`Dataset`), `manifest` (reading and checking manifest.json), `sql` (the SQL names),
`storage` (local or object store), `selection` (which scenes a many-scene job takes).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["Dataset", "DatasetReference", "SceneSelection", "as_dataset", "open_dataset", "select_scenes"]

if TYPE_CHECKING:
    from nuparquet.dataset.core import Dataset, DatasetReference, as_dataset, open_dataset
    from nuparquet.dataset.selection import SceneSelection, select_scenes


def __getattr__(name: str):
    # Loaded on first use: the CLI builds its parsers from `selection` without loading polars.
    if name in ("Dataset", "DatasetReference", "as_dataset", "open_dataset"):
        from nuparquet.dataset import core

        return getattr(core, name)
    if name in ("SceneSelection", "select_scenes"):
        from nuparquet.dataset import selection

        return getattr(selection, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
