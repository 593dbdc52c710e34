"""Lidar points in camera images, as devkit `NuScenesExplorer.map_pointcloud_to_image`.

The poses come from the stored transforms, read once per query (`frames.poses`): the lidar frames'
`sensor_poses` and the cameras' `Cameras`; only the point files are read per frame.

```python
cameras = cameras_from_frames(camera_rows)                   # once
global_from_ego, ego_from_lidar = sensor_poses(lidar_rows)   # once
lidar_of_camera = lidar_for_cameras(camera_rows, lidar_rows)  # (F,) row of each camera's lidar keyframe
j = lidar_of_camera[i]
uv, depth, index = points_in_image(read_lidar_bin(path_j), global_from_ego[j], ego_from_lidar[j], cameras.take([i]))
```
"""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet import geometry
from nuparquet.geometry import Cameras

# devkit map_pointcloud_to_image: min_dist default, and the 1-pixel margin it leaves "for aesthetic reasons".
POINT_MIN_DEPTH_M = 1.0
POINT_MARGIN_PX = 1.0


def points_in_image(
    points_sensor_m: np.ndarray,
    global_from_ego: np.ndarray,
    ego_from_sensor: np.ndarray,
    camera: Cameras,
    min_depth_m: float = POINT_MIN_DEPTH_M,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points of one sensor frame in one camera image, as devkit `map_pointcloud_to_image`.

    Points go sensor -> ego at the sensor's timestamp -> global -> ego at the camera's timestamp -> camera ->
    image, and are kept when depth > min_depth_m and 1 < u < width - 1, 1 < v < height - 1 (the devkit's
    1-pixel margin, on the full-size image even when `camera` is resized). Computed in float64 (the devkit
    rounds to float32 after each step, which moves points by up to ~1e-4 m in the global frame).

    Args:
        points_sensor_m: (P, 3+) points in the sensor frame, metres; extra columns (intensity, ring) ignored.
        global_from_ego: (4, 4) the ego pose at the point sensor's timestamp.
        ego_from_sensor: (4, 4) the point sensor's calibration.
        camera: one camera (`Cameras` of length 1), at full size or resized.
        min_depth_m: points closer to the camera plane are dropped.

    Returns:
        uv (K, 2) pixels of `camera`, depth (K,) metres (camera z), index (K,) int64 rows of `points_sensor_m`.
    """
    if len(camera) != 1:
        raise ValueError(f"points_in_image takes one camera, got {len(camera)}")
    points_sensor_m = np.asarray(points_sensor_m)[:, :3].astype(np.float64)
    # Step by step rather than one composed matrix, the order the devkit applies them.
    points_global_m = geometry.transform_points(global_from_ego, geometry.transform_points(ego_from_sensor,
                                                                                           points_sensor_m))
    points_camera_m = camera.to_camera(points_global_m[None])  # (1, P, 3)
    uv, depth_m = camera.project(points_camera_m)
    keep = (depth_m > min_depth_m) & camera.in_image(uv, margin_px=POINT_MARGIN_PX)
    index = np.flatnonzero(keep[0])
    return uv[0, index], depth_m[0, index], index


def lidar_for_cameras(cameras: pl.DataFrame, lidar: pl.DataFrame) -> np.ndarray:
    """(F,) int64 row of `lidar` (keyframes of one lidar channel) sharing the sample of each keyframe row of
    `cameras`; -1 for sweeps and for samples without such a lidar keyframe (the devkit pairs keyframes)."""
    lidar_rows = lidar.select("sample_token").with_row_index("lidar_row").unique("sample_token", keep="first")
    paired = cameras.select("sample_token", "is_key_frame").join(lidar_rows, on="sample_token", how="left",
                                                                 maintain_order="left")
    return (
        paired.select(pl.when(pl.col("is_key_frame")).then(pl.col("lidar_row").cast(pl.Int64)).fill_null(-1))
        .to_series().to_numpy().astype(np.int64)
    )
