"""The public scene splits of nuScenes (the devkit's `create_splits_scenes`: train, val, test, mini_train, mini_val,
train_detect, train_track) and of MAN TruckScenes (truckscenes-devkit's, the same names), as data read once from
`nuparquet/data/<family>_splits.json`, and the one rule every user of them starts from.

- `scene_splits(family)`: {split: [scene names]}, the devkit's lists ("nuscenes" unless named; a family without
  lists of its own, such as nuImages, has none).
- `known_split(names, version, family)`: the split each scene name is known to belong to (the `split` column of
  `scenes/`): mini_* wins for mini versions, null for names no list holds (synthetic or other datasets).
The training index's own rule (mmdetection3d sends every non-train scene to val) is `nuparquet.index.splits`,
built on these lists.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources

import polars as pl


SPLIT_FAMILIES = ("nuscenes", "truckscenes")  # the families with published split lists


@cache
def scene_splits(family: str = "nuscenes") -> dict[str, list[str]]:
    """{split name: scene names} of the family's devkit `create_splits_scenes` (train, val, test, mini_train,
    mini_val, train_detect, train_track); {} for a family without lists."""
    if family not in SPLIT_FAMILIES:
        return {}
    return json.loads((resources.files("nuparquet") / "data" / f"{family}_splits.json").read_text())


def known_split(names: pl.Series, version: str, family: str = "nuscenes") -> pl.Series:
    """The known split of each scene name (the family's lists); mini_* splits win for mini versions, null for
    unknown names."""
    splits = scene_splits(family)
    if not splits:
        return pl.Series(names.name, [None] * len(names), dtype=pl.String)
    order = (["mini_train", "mini_val"] if "mini" in version else []) + ["train", "val", "test"]
    lookup: dict[str, str] = {}
    for split in reversed(order):  # earlier entries of `order` overwrite later ones
        lookup.update(dict.fromkeys(splits[split], split))
    return names.replace_strict(lookup, default=None, return_dtype=pl.String)
