"""Which scenes an evaluation split holds: the devkit's `create_splits_scenes` lists (train, val, test,
mini_train, mini_val, train_detect, train_track: scene names, in `nuparquet/data/<family>_splits.json`: nuScenes'
or TruckScenes'), or a custom split from `<dataroot>/<version>/splits.json` as the devkit's
`get_scenes_of_custom_split` reads it.

Unlike the devkit, the version folder's name is not checked against the split (the devkit refuses `val` unless
the version ends in "trainval"): a dataset holding some of the split's scenes (an extract, a derived dataset)
is evaluated on those, and the result says how many of the split's scenes it found.
"""

from __future__ import annotations

import json
from pathlib import Path

from nuparquet.errors import UsageError
from nuparquet.splits import scene_splits

PREDEFINED_SPLITS = ("train", "val", "test", "mini_train", "mini_val", "train_detect", "train_track")


def predefined_splits(family: str = "nuscenes") -> dict[str, list[str]]:
    """The devkit's splits by name (`nuparquet.splits`, the one loader of the lists)."""
    return {name: scene_splits(family)[name] for name in PREDEFINED_SPLITS}


def split_scene_names(split: str, *, dataroot: str | None = None, version: str | None = None,
                      family: str = "nuscenes") -> list[str]:
    """The scene names of `split`: a predefined split of the family's devkit, else one of
    `<dataroot>/<version>/splits.json`."""
    if split in PREDEFINED_SPLITS:
        return predefined_splits(family)[split]
    custom = Path(dataroot) / version / "splits.json" if dataroot and version else None
    if custom is None or not custom.is_file():
        where = f" and {custom} does not exist" if custom is not None else ""
        raise UsageError(f"unknown split {split!r}: the nuScenes splits are {', '.join(PREDEFINED_SPLITS)}{where} "
                         "(a custom split is a list of scene names in <dataroot>/<version>/splits.json)")
    try:
        lists = json.loads(custom.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UsageError(f"{custom}: cannot be read as JSON ({exc})") from exc
    if not isinstance(lists, dict) or split not in lists:
        known = ", ".join(sorted(lists)) if isinstance(lists, dict) else "none"
        raise UsageError(f"unknown split {split!r}: not predefined, nor in {custom} (it lists: {known})")
    names = lists[split]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise UsageError(f"{custom}: split {split!r} must be a list of scene names")
    return names


def is_predefined(split: str) -> bool:
    return split in PREDEFINED_SPLITS
