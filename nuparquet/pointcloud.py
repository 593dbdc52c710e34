"""Point cloud files of nuScenes sensors (the readers live in `nuparquet.sources.points`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nuparquet.sources.points import LIDAR_FIELDS, read_lidar_bin

__all__ = ["LIDAR_FIELDS", "load_lidar_bin"]


def load_lidar_bin(path: str | Path) -> np.ndarray:
    """A nuScenes lidar `.pcd.bin` file: (P, 5) float32 [x, y, z, intensity, ring index], lidar frame, metres.

    Raises FileNotFoundError, or `PointFileError` (a ValueError's place: an InputError naming the file) when the
    size is not a whole number of 5-float records."""
    return read_lidar_bin(path, len(LIDAR_FIELDS))
