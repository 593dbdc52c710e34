"""Sensor poses and cameras of `frames` rows, read once per query from the stored transform columns.

`frames` stores `global_from_ego` and `ego_from_sensor` (row-major `[16]`), `camera_intrinsic` (row-major `[9]`,
null for non-cameras), `width` and `height`. Rows that lack the matrix columns (hand-written tables) are
built from the poses (`ego_translation`/`ego_rotation`, `sensor_translation`/`sensor_rotation`) with the
same function the converter uses, so both give the same numbers.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet import columns, geometry
from nuparquet.geometry import Cameras
from nuparquet.geometry.interpolation import closest_rows

MATRIX_COLUMNS = ("global_from_ego", "ego_from_sensor")
POSE_COLUMNS = ("ego_translation", "ego_rotation", "sensor_translation", "sensor_rotation")
CAMERA_COLUMNS = ("camera_intrinsic", "width", "height")


def pose_columns(names) -> tuple[str, ...]:
    """The columns `sensor_poses` reads, given the column names a frames table has: the stored matrices
    when present, else the poses."""
    return MATRIX_COLUMNS if set(MATRIX_COLUMNS) <= set(names) else POSE_COLUMNS


def sensor_poses(frames: pl.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """global_from_ego (F, 4, 4) at each frame's timestamp and ego_from_sensor (F, 4, 4) of `frames` rows."""
    if set(MATRIX_COLUMNS) <= set(frames.columns):
        return (columns.to_numpy(frames["global_from_ego"], (4, 4)),
                columns.to_numpy(frames["ego_from_sensor"], (4, 4)))
    missing = [name for name in POSE_COLUMNS if name not in frames.columns]
    if missing:
        raise ValueError(f"frames lacks column(s) {', '.join(missing)} (or {' and '.join(MATRIX_COLUMNS)})")
    global_from_ego = geometry.rigid_transforms(columns.to_numpy(frames["ego_translation"], (3,)),
                                                columns.to_numpy(frames["ego_rotation"], (4,)))
    ego_from_sensor = geometry.rigid_transforms(columns.to_numpy(frames["sensor_translation"], (3,)),
                                                columns.to_numpy(frames["sensor_rotation"], (4,)))
    return global_from_ego, ego_from_sensor


def cameras_from_frames(frames: pl.DataFrame) -> Cameras:
    """The cameras of F camera rows of `frames` (every row needs a camera_intrinsic), at full image size."""
    missing = [name for name in CAMERA_COLUMNS if name not in frames.columns]
    if missing:
        raise ValueError(f"frames lacks column(s) {', '.join(missing)}")
    if frames["camera_intrinsic"].null_count():
        raise ValueError("cameras_from_frames needs camera rows: some rows have no camera_intrinsic")
    global_from_ego, ego_from_camera = sensor_poses(frames)
    size_px = np.stack([frames["width"].to_numpy(), frames["height"].to_numpy()], axis=1).astype(np.float64)
    return Cameras.from_poses(global_from_ego, ego_from_camera, columns.to_numpy(frames["camera_intrinsic"], (3, 3)),
                              size_px.reshape(-1, 2))


def with_sample_poses(frames: pl.DataFrame, ego_pose: pl.DataFrame, samples: pl.DataFrame) -> pl.DataFrame:
    """`frames` rows with `ego_translation` / `ego_rotation` replaced by the pose nearest each frame's *sample*
    time (`geometry.interpolation.closest_rows`) and the stored matrices dropped: what TruckScenes' devkit `get_sample_data` moves
    the boxes of a frame with (nuScenes' uses the frame's own pose). `ego_pose`: the table (token, timestamp,
    translation, rotation) in file order; `samples`: token, timestamp."""
    sample_time = frames.select("sample_token").join(samples.select(pl.col("token").alias("sample_token"), "timestamp"),
                                                     on="sample_token", how="left", maintain_order="left")["timestamp"]
    rows = closest_rows(ego_pose["timestamp"].to_numpy(), sample_time.to_numpy())
    return frames.drop(*MATRIX_COLUMNS, strict=False).with_columns(
        ego_translation=ego_pose["translation"].gather(rows), ego_rotation=ego_pose["rotation"].gather(rows))
