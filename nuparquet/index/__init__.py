"""Training index: mmdetection3d's nuScenes info files written from a converted directory, without the devkit.

```python
from nuparquet.index import IndexOptions, build_index
paths = build_index("OUT", "infos", IndexOptions(info_version=2))   # {"val": Path(".../nuscenes_infos_val.pkl"), ...}
```

Modules: `build` (`build_index`), `inputs` (what is read, checked first), `splits`, `replay/` (blas, quaternions, transforms: the
converter's arithmetic over arrays, bit for bit), `sweeps` (the lidar prev chain), `compute` (all numbers,
vectorised over samples), `cam_instances` (v2 camera boxes), `v2_arrays` (one split's values with offsets),
`records` (the dicts, v1 and v2), `lidarseg` (pts_semantic_mask_path), `bevformer`, `legacy` (mmdetection3d
0.17's infos and mono3d COCO file), `parquet` (DIR/infos/ from the same arrays), `write` (atomic files, the
streamed pickle).
"""

from __future__ import annotations

__all__ = ["IndexOptions", "build_index"]


def __getattr__(name: str):
    # Loaded on first use: every CLI command builds its parser from the index options, and the builder pulls in
    # polars, the queries and the writers.
    if name == "build_index":
        from nuparquet.index.build import build_index

        return build_index
    if name == "IndexOptions":
        from nuparquet.index.options import IndexOptions

        return IndexOptions
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
