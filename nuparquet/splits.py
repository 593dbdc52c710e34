"""nuScenes' public scene splits (the devkit's `create_splits_scenes`: train, val, test, mini_train, mini_val,
train_detect, train_track), as
data read once from `nuparquet/data/nuscenes_splits.json`, and the one rule every user of them starts from.

- `scene_splits()`: {split: [scene names]}, the devkit's lists.
- `known_split(names, version)`: the split each scene name is known to belong to (the `split` column of
  `scenes/`): mini_* wins for mini versions, null for names no list holds (synthetic or other datasets).
The training index's own rule (mmdetection3d sends every non-train scene to val) is `nuparquet.index.splits`,
built on these lists.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources

import polars as pl


@cache
def scene_splits() -> dict[str, list[str]]:
    """{split name: scene names} of the devkit's `create_splits_scenes` (train, val, test, mini_train, mini_val,
    train_detect, train_track)."""
    return json.loads((resources.files("nuparquet") / "data" / "nuscenes_splits.json").read_text())


def known_split(names: pl.Series, version: str) -> pl.Series:
    """The known nuScenes split of each scene name; mini_* splits win for mini versions, null for unknown names."""
    splits = scene_splits()
    order = (["mini_train", "mini_val"] if "mini" in version else []) + ["train", "val", "test"]
    lookup: dict[str, str] = {}
    for split in reversed(order):  # earlier entries of `order` overwrite later ones
        lookup.update(dict.fromkeys(splits[split], split))
    return names.replace_strict(lookup, default=None, return_dtype=pl.String)
