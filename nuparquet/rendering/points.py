"""Lidar points for camera tiles: each keyframe camera row paired with its sample's reference-lidar keyframe,
the poses read once from the stored transforms, the points projected straight into the tile's camera.

Points come from the dataset's one sensor reader (`ds.sensors`: `lidar_points/` when the frame was converted,
reading only its row groups, else its `.pcd.bin` file). Colours (`--lidar-color`): depth (default), intensity (the
devkit's `render_intensity` scaling), lidarseg (the category colours, `palette.category_rgb`, which are the
devkit's colormap for nuScenes names and a stable hash colour for others) or panoptic (the devkit's colour per
instance, stuff in its class colour): `point_colors`. Labels need `lidar_points/` with labels, or a submission's
predicted labels (`--lidar-predictions`: the challenge classes' colours, `point_colors.challenge_label_rgb`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import polars as pl

from nuparquet.geometry import Cameras
from nuparquet.errors import InputError, UsageError
from nuparquet.rendering.colorings import LIDAR_COLORS
from nuparquet.rendering.point_colors import challenge_label_rgb, intensity_levels, label_rgb
from nuparquet.frames.poses import sensor_poses
from nuparquet.frames.points_in_image import lidar_for_cameras, points_in_image

_LABEL_COLUMN = {"lidarseg": "lidarseg_label", "panoptic": "panoptic_label"}
_POINT_COLUMNS = ["x", "y", "z", "intensity"]


@dataclass(frozen=True)
class CloudReader:
    """The reference-lidar clouds of a render, by lidar row, through the dataset's sensor reader (converted points
    or the files), with the labels the colour mode needs; and their colours. Shared by the camera tiles and the
    bird's-eye view."""

    paths: list[str]  # (L,) point cloud files (what a missing frame is reported as)
    tokens: list[str]  # (L,) sample_data tokens
    filenames: list[str]  # (L,) sample_data filenames
    sensors: object  # the dataset's SensorReader
    color: str = "depth"
    names_by_index: dict[int, str] = field(default_factory=dict)  # category index -> name (label colours)
    predicted: tuple[Path, ...] = ()  # (L,) the submission's label file of each row: colours by its predictions

    @classmethod
    def build(cls, lidar: pl.DataFrame, dataroot: Path, *, dataset, color: str = "depth",
              predictions: str | Path | None = None) -> CloudReader:
        """For the lidar rows `lidar` (`filename`, `token`); UsageError if `color` needs labels the output lacks.
        `predictions`: a lidarseg or panoptic submission folder whose labels colour the points instead of the
        ground truth (`predicted_files`)."""
        if color not in LIDAR_COLORS:
            raise UsageError(f"--lidar-color must be one of {', '.join(LIDAR_COLORS)}, got {color!r}")
        filenames = lidar["filename"].to_list()
        paths = [str(dataroot / name) for name in filenames]
        if predictions is not None:
            return cls(paths, lidar["token"].to_list(), filenames, dataset.sensors, color,
                       predicted=predicted_files(Path(predictions), lidar["token"].to_list(), color))
        names: dict[int, str] = {}
        if color in _LABEL_COLUMN:
            from nuparquet.queries.points import has_labels

            if "lidar_points" not in dataset.datasets or not has_labels(dataset, color):
                raise UsageError(f"--lidar-color {color} needs lidar_points/ with {color} labels (convert the "
                                 "dataroot with --sensors lidar; its lidarseg/panoptic files must be present)")
            categories = dataset.scan("tables/category").select("index", "name").drop_nulls("index").collect()
            names = dict(zip(categories["index"].to_list(), categories["name"].to_list()))
        return cls(paths, lidar["token"].to_list(), filenames, dataset.sensors, color, names)

    def cloud(self, lidar: int) -> tuple[np.ndarray, np.ndarray | None]:
        """(P, 4) x, y, z, intensity of lidar row `lidar` and its (P,) labels for the colour mode (or None)."""
        if self.predicted:
            return self._predicted_cloud(lidar)
        label = _LABEL_COLUMN.get(self.color)
        columns = [*_POINT_COLUMNS, *([label] if label else [])]
        frame = self.sensors.points(self.tokens[lidar], self.filenames[lidar], "lidar", columns)
        if label and label not in frame.columns:  # a frame left out of lidar_points/: its file has no labels
            raise FileNotFoundError(self.paths[lidar])
        points = frame.select(_POINT_COLUMNS).to_numpy().astype(np.float32)
        return points, (frame[label].to_numpy() if label else None)

    def _predicted_cloud(self, lidar: int) -> tuple[np.ndarray, np.ndarray]:
        from nuparquet.frames.sweeps import read_point_file
        from nuparquet.sources.points import read_lidarseg_bin, read_panoptic_npz

        frame = self.sensors.points(self.tokens[lidar], self.filenames[lidar], "lidar", _POINT_COLUMNS)
        points = frame.select(_POINT_COLUMNS).to_numpy().astype(np.float32)
        path = self.predicted[lidar]
        reader = read_panoptic_npz if self.color == "panoptic" else read_lidarseg_bin
        labels = read_point_file(reader, path).astype(np.int64)
        if len(labels) != len(points):
            raise InputError(f"{path} holds {len(labels)} predicted labels for the {len(points)} points of lidar "
                             f"sample_data {self.tokens[lidar]}")
        return points, labels

    def colors_bgr(self, points: np.ndarray, labels: np.ndarray | None, index: np.ndarray) -> np.ndarray | None:
        """(K, 3) BGR uint8 colours of the kept points `index`, or None for the depth colouring."""
        if self.color == "depth":
            return None
        if self.predicted:
            return challenge_label_rgb(labels[index], self.color)[:, ::-1].copy()
        if self.color == "intensity":
            levels = np.rint(255.0 * 2.0 * intensity_levels(points[:, 3])[index]).astype(np.uint8)  # [0, .5] -> [0, 255]
            return cv2.applyColorMap(levels.reshape(-1, 1), cv2.COLORMAP_VIRIDIS).reshape(-1, 3)
        return label_rgb(labels[index], self.color, self.names_by_index)[:, ::-1].copy()


def predicted_files(folder: Path, tokens: list[str], color: str) -> tuple[Path, ...]:
    """The label file of each lidar sample_data token in a submission folder: `<token>_lidarseg.bin` or
    `<token>_panoptic.npz` at any depth (the devkit's `lidarseg/<split>/` and `panoptic/<split>/` layouts);
    UsageError naming the first token without one, or a token with two."""
    if not folder.is_dir():
        raise UsageError(f"--lidar-predictions {folder}: not a folder (a lidarseg or panoptic submission)")
    suffix = "_panoptic.npz" if color == "panoptic" else "_lidarseg.bin"
    found: dict[str, list[Path]] = {}
    for path in sorted(folder.rglob(f"*{suffix}")):
        found.setdefault(path.name[: -len(suffix)], []).append(path)
    files = []
    for token in tokens:
        paths = found.get(token, [])
        if len(paths) != 1:
            what = "no" if not paths else f"{len(paths)} files ({', '.join(map(str, paths))}), not one"
            raise UsageError(f"--lidar-predictions {folder}: {what} {token}{suffix} for lidar sample_data {token}")
        files.append(paths[0])
    return tuple(files)


@dataclass(frozen=True)
class LidarPoints:
    """The lidar keyframes of a render and, per camera row, which one it shows."""

    tile_cameras: Cameras  # (F,) the cameras of the camera rows, resized to the tile
    lidar_of_camera: np.ndarray  # (F,) row of the lidar keyframe each camera row shows, -1 for none
    global_from_ego: np.ndarray  # (L, 4, 4)
    ego_from_sensor: np.ndarray  # (L, 4, 4)
    reader: CloudReader

    @classmethod
    def build(cls, tile_cameras: Cameras, cameras: pl.DataFrame, lidar: pl.DataFrame, dataroot: Path, *,
              dataset, color: str = "depth", predictions: str | Path | None = None) -> LidarPoints:
        reader = CloudReader.build(lidar, dataroot, dataset=dataset, color=color, predictions=predictions)
        global_from_ego, ego_from_sensor = sensor_poses(lidar)
        return cls(tile_cameras, lidar_for_cameras(cameras, lidar), global_from_ego, ego_from_sensor, reader)

    @property
    def paths(self) -> list[str]:
        return self.reader.paths

    def load(self, row: int) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray | None] | None, str | None]:
        """(uv (K, 2) tile pixels, depth (K,), colours (K, 3) BGR uint8 or None for the depth colours) of camera
        row `row`'s lidar points, or None; and the path of a missing or unreadable point cloud (else None)."""
        lidar = int(self.lidar_of_camera[row])
        if lidar < 0:
            return None, None
        try:
            points, labels = self.reader.cloud(lidar)
        except (OSError, ValueError):
            return None, self.reader.paths[lidar]
        uv, depth, index = points_in_image(points, self.global_from_ego[lidar], self.ego_from_sensor[lidar],
                                          self.tile_cameras.take([row]))
        return (uv, depth, self.reader.colors_bgr(points, labels, index)), None
