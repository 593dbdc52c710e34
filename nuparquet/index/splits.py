"""Which info file each sample goes to, as mmdetection3d's `create_nuscenes_infos` decides: the devkit's public
scene lists for the version (mini versions use mini_train / mini_val, a test version puts everything in
`test`), and every sample whose scene is not in the train list goes to val."""

from __future__ import annotations

import numpy as np

from nuparquet.errors import UsageError
from nuparquet.splits import scene_splits

CONVERTER_VERSIONS = ("v1.0-trainval", "v1.0-test", "v1.0-mini")


def converter_version(dataset_version: str | None, given: str | None) -> str:
    """The version the converter would be run with: `given`, else the one `dataset_version` starts with."""
    if given is not None:
        if given not in CONVERTER_VERSIONS:
            raise UsageError(f"--version must be one of {', '.join(CONVERTER_VERSIONS)} (mmdetection3d's choices)")
        return given
    for version in CONVERTER_VERSIONS:
        if (dataset_version or "").startswith(version):
            return version
    raise UsageError(f"cannot tell which nuScenes version {dataset_version!r} stands for: pass --version "
                     f"({', '.join(CONVERTER_VERSIONS)})")


def split_names(version: str) -> tuple[str, ...]:
    """The files the converter writes for `version`."""
    return ("test",) if version == "v1.0-test" else ("train", "val")


def assign_splits(version: str, scene_token: np.ndarray, scene_name: np.ndarray,
                  sample_scene: np.ndarray) -> np.ndarray:
    """(S,) the split name of each sample ("train", "val" or "test")."""
    if version == "v1.0-test":
        return np.full(len(sample_scene), "test", dtype=object)
    lists = scene_splits()
    train = lists["mini_train" if version == "v1.0-mini" else "train"]
    train_tokens = scene_token[np.isin(scene_name, train)]
    return np.where(np.isin(sample_scene, train_tokens), "train", "val").astype(object)
