"""Lidar points for camera tiles: each keyframe camera row paired with its sample's reference-lidar keyframe,
the poses read once from the stored transforms, the points projected straight into the tile's camera."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.camera import Cameras
from nuparquet.pointcloud import load_lidar_bin
from nuparquet.projection.frames import sensor_poses
from nuparquet.projection.lidar import lidar_for_cameras, project_points


@dataclass(frozen=True)
class LidarPoints:
    """The lidar keyframes of a render and, per camera row, which one it shows."""

    tile_cameras: Cameras  # (F,) the cameras of the camera rows, resized to the tile
    lidar_of_camera: np.ndarray  # (F,) row of the lidar keyframe each camera row shows, -1 for none
    paths: list[str]  # (L,) point cloud files
    global_from_ego: np.ndarray  # (L, 4, 4)
    ego_from_sensor: np.ndarray  # (L, 4, 4)

    @classmethod
    def build(cls, tile_cameras: Cameras, cameras: pl.DataFrame, lidar: pl.DataFrame, dataroot: Path) -> LidarPoints:
        global_from_ego, ego_from_sensor = sensor_poses(lidar)
        return cls(tile_cameras, lidar_for_cameras(cameras, lidar),
                   [str(dataroot / name) for name in lidar["filename"].to_list()], global_from_ego, ego_from_sensor)

    def load(self, row: int) -> tuple[tuple[np.ndarray, np.ndarray] | None, str | None]:
        """(uv (K, 2) tile pixels, depth (K,)) of camera row `row`'s lidar points, or None; and the path of a
        missing or unreadable point cloud (else None)."""
        lidar = int(self.lidar_of_camera[row])
        if lidar < 0:
            return None, None
        try:
            points = load_lidar_bin(self.paths[lidar])
        except (OSError, ValueError):
            return None, self.paths[lidar]
        uv, depth, _ = project_points(points, self.global_from_ego[lidar], self.ego_from_sensor[lidar],
                                      self.tile_cameras.take([row]))
        return (uv, depth), None
