"""Point cloud files of nuScenes sensors."""

from __future__ import annotations

from pathlib import Path

import numpy as np

LIDAR_FIELDS = ("x", "y", "z", "intensity", "ring")


def load_lidar_bin(path: str | Path) -> np.ndarray:
    """A lidar `.pcd.bin` file: little-endian float32 records of 5 values.

    Args:
        path: the file (`samples/LIDAR_TOP/*.pcd.bin` or `sweeps/LIDAR_TOP/*.pcd.bin`).

    Returns:
        (P, 5) float32 [x, y, z, intensity, ring index]; x, y, z in the lidar frame, metres.

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: the file size is not a whole number of 5-float records.
    """
    raw = np.fromfile(path, dtype="<f4")
    if raw.size % len(LIDAR_FIELDS):
        raise ValueError(
            f"{path}: {raw.size * 4} bytes is not a whole number of {len(LIDAR_FIELDS)}-float32 lidar points"
        )
    return raw.reshape(-1, len(LIDAR_FIELDS)).astype(np.float32, copy=False)
