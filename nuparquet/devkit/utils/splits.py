"""The devkit's `nuscenes.utils.splits`: nuScenes' official scene lists (`train`, `val`, `test`, `mini_train`,
`mini_val`, `train_detect`, `train_track`, as `nuparquet.splits` reads them) and the functions
over them."""

from __future__ import annotations

import json
import os

from nuparquet.splits import scene_splits

_LISTS: dict[str, list[str]] = scene_splits()

train_detect: list[str] = _LISTS["train_detect"]
train_track: list[str] = _LISTS["train_track"]
train: list[str] = _LISTS["train"]
val: list[str] = _LISTS["val"]
test: list[str] = _LISTS["test"]
mini_train: list[str] = _LISTS["mini_train"]
mini_val: list[str] = _LISTS["mini_val"]


def create_splits_logs(split: str, nusc) -> list[str]:
    """The log files of the scenes of `split` present in `nusc` (the split must suit `nusc.version`)."""
    scene_splits = create_splits_scenes(verbose=False)
    assert split in scene_splits.keys(), "Requested split {} which is not a known nuScenes split.".format(split)
    version = nusc.version
    if split in {"train", "val", "train_detect", "train_track"}:
        assert version.endswith("trainval"), \
            "Requested split {} which is not compatible with NuScenes version {}".format(split, version)
    elif split in {"mini_train", "mini_val"}:
        assert version.endswith("mini"), \
            "Requested split {} which is not compatible with NuScenes version {}".format(split, version)
    elif split == "test":
        assert version.endswith("test"), \
            "Requested split {} which is not compatible with NuScenes version {}".format(split, version)
    else:
        raise ValueError("Requested split {} which this function cannot map to logs.".format(split))
    scene_to_log = {scene["name"]: nusc.get("log", scene["log_token"])["logfile"] for scene in nusc.scene}
    logs = set()
    for scene in scene_splits[split]:
        logs.add(scene_to_log[scene])
    return list(logs)


def create_splits_scenes(verbose: bool = False) -> dict[str, list[str]]:
    """{split name: scene names} for the seven predefined splits (the lists themselves, as the devkit)."""
    all_scenes = train + val + test
    assert len(all_scenes) == 1000 and len(set(all_scenes)) == 1000, "Error: Splits incomplete!"
    scene_splits = {"train": train, "val": val, "test": test, "mini_train": mini_train, "mini_val": mini_val,
                    "train_detect": train_detect, "train_track": train_track}
    if verbose:
        for split, scenes in scene_splits.items():
            print("%s: %d" % (split, len(scenes)))
            print("%s" % scenes)
    return scene_splits


def get_scenes_of_split(split_name: str, nusc, verbose: bool = False) -> list[str]:
    """The scene names of a predefined split, or of a custom split from `<dataroot>/<version>/splits.json`."""
    if is_predefined_split(split_name=split_name):
        return create_splits_scenes(verbose=verbose)[split_name]
    return get_scenes_of_custom_split(split_name=split_name, nusc=nusc)


def is_predefined_split(split_name: str) -> bool:
    return split_name in create_splits_scenes().keys()


def get_scenes_of_custom_split(split_name: str, nusc) -> list[str]:
    """The scene names of `split_name` in `<dataroot>/<version>/splits.json`."""
    splits_file_path = _get_custom_splits_file_path(nusc)
    with open(splits_file_path) as file:
        splits_data = json.load(file)
    if split_name not in splits_data.keys():
        raise ValueError(f"Custom split {split_name} requested, but not found in {splits_file_path}.")
    scene_names_of_split = splits_data[split_name]
    assert isinstance(scene_names_of_split, list), \
        f"Custom split {split_name} must be a list of scene names in {splits_file_path}."
    return scene_names_of_split


def _get_custom_splits_file_path(nusc) -> str:
    splits_file_path = os.path.join(nusc.dataroot, nusc.version, "splits.json")
    if not os.path.isfile(splits_file_path):
        raise ValueError(f"Custom split requested, but no valid file found at {splits_file_path}.")
    return splits_file_path
