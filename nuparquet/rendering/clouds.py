"""One frame's rows, points and point labels for a single picture (`sample_data`, `pointcloud_image`, `annotation`):
read from the converted datasets where they are, else from the files under the dataroot.

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

from nuparquet.errors import InputError, UsageError

_POINT_COLUMNS = ["x", "y", "z", "intensity"]
_LABEL_COLUMN = {"lidarseg": "lidarseg_label", "panoptic": "panoptic_label"}


@dataclass(frozen=True)
class Cloud:
    """points: (P, 4) float32 x, y, z, intensity in the sensor frame; labels: (P,) int64 or None."""

    points: np.ndarray
    labels: np.ndarray | None = None


def dataroot_of(dataset, given=None) -> Path:
    """Where the sensor files are: `given`, else the dataroot recorded at conversion; UsageError if it is not there."""
    root = Path(given) if given is not None else (Path(dataset.dataroot) if dataset.dataroot else None)
    if root is None or not root.is_dir():
        raise UsageError(f"the dataroot {root} (where the sensor files are) does not exist; pass dataroot=PATH "
                         "(--dataroot on the command line)")
    return root


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


def lidar_cloud(dataset, row: dict, dataroot: Path, *, labels: str | None = None,
                preds_path: str | Path | None = None) -> Cloud:
    """The lidar frame `row`'s points and, for `labels` ("lidarseg" or "panoptic"), its labels: from `preds_path`
    when given, else the ground truth (lidar_points/ or the label file the index table names)."""
    column = _LABEL_COLUMN.get(labels) if labels else None
    points = truth = None
    if "lidar_points" in dataset.datasets:
        try:
            frame = dataset.points(row["token"], columns=_POINT_COLUMNS + ([column] if column else []))
        except UsageError:  # this frame was not converted: its file
            frame = None
        if frame is not None:
            points = frame.select(_POINT_COLUMNS).to_numpy().astype(np.float32)
            if column and frame[column].null_count() == 0:
                truth = frame[column].to_numpy().astype(np.int64)
    if points is None:
        from nuparquet.frames.sweeps import read_point_file
        from nuparquet.sources.points import read_lidar_bin

        points = read_point_file(read_lidar_bin, _inside(dataroot, row["filename"]))[:, :4]
    if not labels:
        return Cloud(points)
    if preds_path is not None:
        found = _read_labels(Path(preds_path), labels)
        what = f"predictions file {preds_path}"
    else:
        found = truth if truth is not None else _truth_from_files(dataset, row, dataroot, labels)
        what = f"{labels} labels of sample_data {row['token']}"
    if len(found) != len(points):
        raise InputError(f"{what} hold {len(found)} labels for {len(points)} points")
    return Cloud(points, found)


def _inside(dataroot: Path, filename: str) -> Path:
    relative = Path(filename)
    if relative.is_absolute() or ".." in relative.parts:
        raise InputError(f"{filename}: outside the dataroot, refused")
    return dataroot / relative


def _read_labels(path: Path, labels: str) -> np.ndarray:
    from nuparquet.sources.points import read_lidarseg_bin, read_panoptic_npz

    from nuparquet.frames.sweeps import read_point_file

    if not path.is_file():
        raise InputError(f"no labels file {path}")
    if labels == "panoptic" or path.suffix == ".npz":
        return read_point_file(read_panoptic_npz, path).astype(np.int64)
    return read_point_file(read_lidarseg_bin, path).astype(np.int64)


def _truth_from_files(dataset, row: dict, dataroot: Path, labels: str) -> np.ndarray:
    """The label file `tables/lidarseg` (or `tables/panoptic`) names for the frame."""
    if f"tables/{labels}" not in dataset.datasets:
        raise UsageError(f"{dataset.root} has no {labels} labels (the dataroot had no {labels}.json when converted)")
    names = (dataset.scan(f"tables/{labels}").filter(pl.col("sample_data_token") == row["token"])
             .select("filename").collect())
    if names.is_empty():
        raise UsageError(f"sample_data {row['token']} has no {labels} labels (only lidar keyframes have them)")
    return _read_labels(_inside(dataroot, names["filename"][0]), labels)
