"""One frame's rows, points and point labels for a single picture (`sample_data`, `pointcloud_image`, `annotation`),
through the dataset's sensor reader (`ds.sensors`: the converted datasets where they are, else the files under the
dataroot).

- `frame_row(ds, token)`: the `frames` row of a sample_data token (UsageError naming an unknown one).
- `lidar_cloud(ds, row, labels=...)`: (P, 4) x, y, z, intensity as the devkit's `LidarPointCloud.from_file` loads
  them (every point, in the sensor frame), with the ground-truth lidarseg or panoptic labels of the frame, or a
  predictions file (`lidarseg_preds_bin_path`: a `.bin` of uint8 classes or a panoptic `.npz`).
- `category_names(ds)`: class index -> category name (`tables/category`'s `index`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import InputError


@dataclass(frozen=True)
class Cloud:
    """points: (P, 4) float32 x, y, z, intensity in the sensor frame; labels: (P,) int64 or None."""

    points: np.ndarray
    labels: np.ndarray | None = None


def frame_row(dataset, token: str) -> dict:
    """The `frames` row of sample_data `token` as a dict (channel and modality as strings)."""
    rows = dataset.frame_rows(token).with_columns(pl.col("channel").cast(pl.String),
                                                  pl.col("modality").cast(pl.String)).collect()
    return rows.row(0, named=True)


def frame_frame(dataset, token: str) -> pl.DataFrame:
    """The `frames` row of sample_data `token` as a one-row DataFrame (for the frame-level functions)."""
    return dataset.frame_rows(token).with_columns(pl.col("channel").cast(pl.String),
                                                  pl.col("modality").cast(pl.String)).collect()


def category_names(dataset) -> dict[int, str]:
    """{class index: category name} from `tables/category` (categories without an index left out)."""
    categories = dataset.scan("tables/category").select("index", "name").drop_nulls("index").collect()
    return dict(zip(categories["index"].cast(pl.Int64).to_list(), categories["name"].to_list()))


def lidar_cloud(dataset, row: dict, *, labels: str | None = None, preds_path: str | Path | None = None) -> Cloud:
    """The lidar frame `row`'s points and, for `labels` ("lidarseg" or "panoptic"), its labels: from `preds_path`
    when given, else the ground truth (the dataset's sensor reader: lidar_points/ or the label file)."""
    if preds_path is None or not labels:
        points, truth = dataset.sensors.lidar(row["token"], row["filename"], labels=labels)
        return Cloud(points, truth)
    points, _ = dataset.sensors.lidar(row["token"], row["filename"])
    found = _read_labels(Path(preds_path), labels)
    if len(found) != len(points):
        raise InputError(f"predictions file {preds_path} hold {len(found)} labels for {len(points)} points")
    return Cloud(points, found)


def _read_labels(path: Path, labels: str) -> np.ndarray:
    from nuparquet.sources.points import read_lidarseg_bin, read_panoptic_npz

    from nuparquet.frames.sweeps import read_point_file

    if not path.is_file():
        raise InputError(f"no labels file {path}")
    if labels == "panoptic" or path.suffix == ".npz":
        return read_point_file(read_panoptic_npz, path).astype(np.int64)
    return read_point_file(read_lidarseg_bin, path).astype(np.int64)
