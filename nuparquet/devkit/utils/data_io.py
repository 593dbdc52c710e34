"""The devkit's `nuscenes.utils.data_io`: lidarseg and panoptic label files (read by `nuparquet.sources.points`)."""

from __future__ import annotations

import os

import numpy as np

from nuparquet.sources.points import read_lidarseg_bin


def load_bin_file(bin_path: str, type: str = "lidarseg") -> np.ndarray:  # noqa: A002 - the devkit's keyword
    """(P,) labels of one lidar frame: uint8 class indices (`type="lidarseg"`, a `.bin`) or the panoptic labels
    (`type="panoptic"`, an `.npz`: class index * 1000 + instance id), as the devkit returns them."""
    assert os.path.exists(bin_path), "Error: Unable to find {}.".format(bin_path)
    if type == "lidarseg":
        content = read_lidarseg_bin(bin_path)
    elif type == "panoptic":
        with np.load(bin_path) as archive:  # the devkit returns the array with its stored dtype
            content = archive["data"]
    else:
        raise TypeError(f"Only lidarseg/panoptic type is supported, received {type}")
    assert len(content) > 0, "Error: {} is empty.".format(bin_path)
    return content


def panoptic_to_lidarseg(panoptic_labels: np.ndarray) -> np.ndarray:
    """(P,) uint8 class indices of panoptic labels (instance id + 1000 * class index)."""
    return (panoptic_labels // 1000).astype(np.uint8)


__all__ = ["load_bin_file", "panoptic_to_lidarseg"]
