"""A keyframe's points with those of its previous sweeps, in the reference sensor's frame: devkit
`LidarPointCloud.from_file_multisweep` / `RadarPointCloud.from_file_multisweep`, step for step.

From the sample's keyframe of `channel`, `nsweeps` frames are taken back along the `prev` chain (fewer at the start
of a scene). Each cloud drops the points within `min_distance_m` of its sensor on both x and y (`remove_close`), then
moves sensor -> ego at its own time -> global -> ego at the reference keyframe's time -> reference sensor with one
composed matrix (the devkit's `reduce(np.dot, [ref_from_car, car_from_global, global_from_car, car_from_current])`);
lidar points are rounded back to float32 after the move, as the devkit stores them. `times_s` is the reference time
minus the sweep's, per point. A TruckScenes dataset follows truckscenes-devkit: lidar points stay float64 and each
one's time is its own (the `.pcd`'s `timestamp` field); radar velocities (`vrel_x`, `vrel_y`, `vrel_z`) turn with the
points.

Points come from `lidar_points/` / `radar_points/` where the frame was converted (keyframes, or every frame with
`convert --sweeps`), else from the sensor files under the dataroot; radar keeps the devkit's default filters unless
`radar_filters=False` (the devkit's `RadarPointCloud.disable_filters()`).

```python
sweeps = multisweep(ds, sample_token, "LIDAR_TOP", nsweeps=5)
sweeps.points      # (N, 4) float32 x, y, z, intensity in the LIDAR_TOP keyframe's frame (the devkit's pc.points.T)
sweeps.times_s     # (N,) float64 seconds before the reference keyframe (the devkit's `times`, flattened)
```
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import reduce
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import UsageError
from nuparquet.frames.poses import sensor_poses
from nuparquet.geometry import invert_rigid

SWEEP_COLUMNS = ("token", "sample_token", "scene_name", "channel", "modality", "timestamp", "is_key_frame", "prev",
                 "filename", "global_from_ego", "ego_from_sensor")
LIDAR_COLUMNS = ("x", "y", "z", "intensity")  # the devkit's LidarPointCloud keeps 4 of the 5 stored values
MIN_DISTANCE_M = 1.0  # from_file_multisweep's default


@dataclass(frozen=True)
class Sweeps:
    """Points of a keyframe and its previous sweeps in the reference sensor's frame.

    points: (N, F) float32 x, y, z, intensity for lidar; float64 every PCD field for radar (x, y, z first).
    times_s: (N,) float64 reference time minus the point's sweep time, seconds.
    sweep: (N,) int64 0 for the keyframe, 1 for the sweep before it, ...
    tokens: the sample_data token of each sweep, keyframe first.
    fields: the names of the point columns.
    """

    points: np.ndarray
    times_s: np.ndarray
    sweep: np.ndarray
    tokens: tuple[str, ...]
    fields: tuple[str, ...]


def keyframe_rows(dataset, sample_token: str, channels: list[str]) -> pl.DataFrame:
    """The keyframes of `channels` in the sample (the devkit's `sample['data'][channel]`), one row each; UsageError
    naming a channel the sample has no keyframe of."""
    rows = (dataset.scan("frames").filter((pl.col("sample_token") == sample_token) & pl.col("is_key_frame")
                                          & pl.col("channel").cast(pl.String).is_in(channels))
            .select(SWEEP_COLUMNS).with_columns(pl.col("channel").cast(pl.String), pl.col("modality").cast(pl.String))
            .collect())
    missing = [c for c in channels if c not in set(rows["channel"].to_list())]
    if missing:
        raise UsageError(f"sample {sample_token!r} has no {', '.join(missing)} keyframe")
    return rows


def multisweep(dataset, sample_token: str, channel: str, ref_channel: str | None = None, nsweeps: int = 5,
               min_distance_m: float = MIN_DISTANCE_M, *, radar_filters: bool = True) -> Sweeps:
    """The points of the sample's `channel` keyframe and up to `nsweeps - 1` sweeps before it, in the frame of the
    sample's `ref_channel` keyframe (default: the dataset's reference lidar). See the module docstring."""
    if nsweeps < 1:
        raise UsageError(f"nsweeps must be at least 1, got {nsweeps}")
    ref_channel = ref_channel or dataset.channels.get("reference_lidar")
    keyframes = keyframe_rows(dataset, sample_token, list(dict.fromkeys([channel, ref_channel])))
    ref = keyframes.filter(pl.col("channel") == ref_channel)
    start = keyframes.filter(pl.col("channel") == channel)
    chain = _chain(dataset, start, nsweeps)
    global_from_ref_ego, ref_ego_from_ref = sensor_poses(ref)
    ref_from_car, car_from_global = invert_rigid(ref_ego_from_ref[0]), invert_rigid(global_from_ref_ego[0])
    global_from_car, car_from_current = sensor_poses(chain)
    ref_time_s = 1e-6 * int(ref["timestamp"][0])
    modality = start["modality"][0]
    truck = dataset.source_format == "truckscenes"
    clouds, times, sweep_of = [], [], []
    fields: tuple[str, ...] = ()
    for k, row in enumerate(chain.iter_rows(named=True)):
        point_times = None
        if truck and modality == "lidar":  # truckscenes-devkit: float64 points, each with its own timestamp
            frame = dataset.sensors.points(row["token"], row["filename"], "lidar", [*LIDAR_COLUMNS, "point_timestamp"])
            cloud, fields = frame.select(LIDAR_COLUMNS).to_numpy().astype(np.float64), LIDAR_COLUMNS
            point_times = frame["point_timestamp"].to_numpy()
        else:
            cloud, fields = frame_cloud(dataset, row, modality, radar_filters)
        close = (np.abs(cloud[:, 0]) < min_distance_m) & (np.abs(cloud[:, 1]) < min_distance_m)
        cloud = cloud[~close]
        ref_from_current = reduce(np.dot, [ref_from_car, car_from_global, global_from_car[k], car_from_current[k]])
        # the devkit's `transform`: the 4x4 matrix times homogeneous points, one product
        moved = ref_from_current.dot(np.vstack((cloud[:, :3].T, np.ones(len(cloud)))))[:3].T
        cloud = cloud.copy()
        if truck and modality == "radar":  # truckscenes-devkit's radar `transform` also turns vrel_x, vrel_y, vrel_z
            cloud[:, 3:6] = np.dot(np.hstack((ref_from_current[:, :3], np.identity(4)[:, 3][:, None])),
                                   np.vstack((cloud[:, 3:6].T, np.ones(len(cloud)))))[:3].T
        cloud[:, :3] = moved  # float32 clouds round back to float32, as the devkit's points array does
        clouds.append(cloud)
        if point_times is not None:
            times.append(ref_time_s - 1e-6 * point_times[~close])
        else:
            times.append(np.full(len(cloud), ref_time_s - 1e-6 * int(row["timestamp"])))
        sweep_of.append(np.full(len(cloud), k, dtype=np.int64))
    dtype = np.float32 if modality == "lidar" and not truck else np.float64
    points = np.concatenate(clouds).astype(dtype, copy=False) if clouds else np.zeros((0, len(fields)), dtype)
    return Sweeps(points, np.concatenate(times), np.concatenate(sweep_of), tuple(chain["token"].to_list()), fields)


def _chain(dataset, start: pl.DataFrame, nsweeps: int) -> pl.DataFrame:
    """The start row and up to nsweeps - 1 rows before it along `prev`, in that order."""
    row = start.row(0, named=True)
    frames = (dataset.scan("frames").filter((pl.col("scene_name") == row["scene_name"])
                                            & (pl.col("channel").cast(pl.String) == row["channel"]))
              .select(SWEEP_COLUMNS).with_columns(pl.col("channel").cast(pl.String), pl.col("modality").cast(pl.String))
              .collect())
    position = dict(zip(frames["token"].to_list(), range(frames.height)))
    order, token = [], row["token"]
    while len(order) < nsweeps and token in position:
        order.append(position[token])
        token = frames["prev"][position[token]]
    return frames[order]


def frame_cloud(dataset, row: dict, modality: str, radar_filters: bool = True) -> tuple[np.ndarray, tuple[str, ...]]:
    """(P, F) points of one frame as the devkit's `LidarPointCloud.from_file` / `RadarPointCloud.from_file` loads
    them (lidar: x, y, z, intensity; radar: every PCD field, filtered unless `radar_filters` is False), and their
    field names, through the dataset's sensor reader (converted points, else the file). `row`: the frame's `frames`
    row (token, channel, filename)."""
    if modality == "lidar":
        points, _ = dataset.sensors.lidar(row["token"], row["filename"])
        return points, LIDAR_COLUMNS
    if modality != "radar":
        raise UsageError(f"{row['channel']} is a {modality} channel: sweeps aggregate lidar and radar points")
    from nuparquet.frames.points import FramesNotConverted

    if dataset.sensors.converted_columns("radar"):
        try:
            frame = dataset.radar_points(row["token"], filtered=radar_filters)
            return frame, tuple(_radar_fields(dataset))
        except FramesNotConverted:  # not converted (a sweep): its file
            pass
    from nuparquet.sources.points import passes_default_filters, read_radar_pcd

    path = dataset.sensors.file(row["token"], row["filename"], "radar")
    structured = read_point_file(read_radar_pcd, path)
    names = structured.dtype.names
    if len(structured) and any(np.isnan(structured[0][n]) for n in names if structured.dtype[n].kind == "f"):
        return np.zeros((0, len(names))), names  # a NaN first point: the devkit's empty cloud
    values = np.stack([structured[n].astype(np.float64) for n in names], axis=1) if len(structured) else \
        np.zeros((0, len(names)))
    if radar_filters:
        keep = passes_default_filters(structured)
        if keep is not None:
            values = values[keep]
    return values, names


def read_point_file(reader, path: Path):
    """`reader(path)`, a missing or unreadable file an InputError naming it (a sweep's file is often not there: the
    sweeps are a download of their own)."""
    from nuparquet.errors import InputError

    try:
        return reader(path)
    except FileNotFoundError:
        raise InputError(f"missing point file: {path}") from None
    except OSError as exc:
        raise InputError(f"unreadable point file: {path} ({exc.strerror or exc})") from None


def _radar_fields(dataset) -> list[str]:
    """The PCD fields of radar_points/, in header order (what `Dataset.radar_points` returns)."""
    from nuparquet.frames.points import FRAME_COLUMNS

    names = dataset.scan("radar_points").collect_schema().names()
    return [n for n in names if n not in FRAME_COLUMNS and n != "passes_default_filters"]
