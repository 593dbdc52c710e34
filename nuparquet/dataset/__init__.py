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
`storage` (local or object store).
"""

from nuparquet.dataset.core import Dataset, as_dataset, open_dataset

__all__ = ["Dataset", "as_dataset", "open_dataset"]
