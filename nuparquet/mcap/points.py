"""The point records of lidar and radar frames, as packed structured arrays ready for a foxglove.PointCloud.

Read through the dataset's sensor reader (`ds.sensors`: `lidar_points/` / `radar_points/` when the frame was
converted, else its file); both give the same record layout, so the MCAP bytes do not depend on where the points
came from:

- lidar: x, y, z, intensity, ring as float32 (the `.pcd.bin` record; ring left out when the files have no 5th
  value), then `lidarseg_label` (uint8) and `panoptic_label` (uint16) when the frame was converted with labels;
- radar: the PCD record exactly as its header declares it (FIELDS, SIZE, TYPE: x y z dyn_prop id rcs ... for
  nuScenes), which is also how `radar_points/` types its columns.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.frames.points import FRAME_COLUMNS as POINTS_FRAME_COLUMNS
from nuparquet.sources.points import LIDAR_FIELDS, radar_from_bytes

LABEL_FIELDS = (("lidarseg_label", "u1"), ("panoptic_label", "<u2"))


def records(columns: dict[str, np.ndarray]) -> np.ndarray:
    """(P,) packed structured array of equal-length columns, fields in the order given."""
    dtype = np.dtype([(name, values.dtype.newbyteorder("<")) for name, values in columns.items()])
    out = np.empty(len(next(iter(columns.values()))) if columns else 0, dtype=dtype)
    for name, values in columns.items():
        out[name] = values
    return out


def lidar_records_from_frame(frame: pl.DataFrame) -> np.ndarray:
    """(P,) records of one frame's `lidar_points` rows: the file's float32 record (ring as the float it was in
    the file: the converter checked it is an integer 0..255), then the labels that are not null."""
    columns = {name: frame[name].cast(pl.Float32).to_numpy() for name in LIDAR_FIELDS[:4]}  # file or converted
    if "ring" in frame.columns and frame["ring"].null_count() < frame.height:
        columns["ring"] = frame["ring"].cast(pl.Float32).to_numpy()
    for name, dtype in LABEL_FIELDS:
        if name in frame.columns and frame.height and frame[name].null_count() == 0:
            columns[name] = frame[name].to_numpy().astype(dtype)
    return records(columns)


class PointReader:
    """Points of one scene's lidar and radar frames by sample_data token, through the dataset's sensor reader
    (radar read once per channel from `radar_points/`: its frames share row groups)."""

    def __init__(self, dataset, scene: str):
        self.dataset = dataset
        self.scene = scene
        self.sensors = dataset.sensors
        self.has_radar = bool(self.sensors.converted_columns("radar"))
        self._lidar_columns = [*LIDAR_FIELDS, *(name for name, _ in LABEL_FIELDS)]
        self._radar: dict[str, dict[str, np.ndarray]] = {}  # channel -> token -> records

    def lidar(self, token: str, filename: str) -> np.ndarray:
        return lidar_records_from_frame(self.sensors.points(token, filename, "lidar", self._lidar_columns))

    def radar(self, token: str, channel: str, filename: str) -> np.ndarray:
        if self.has_radar:
            frames = self._radar.get(channel)
            if frames is None:
                frames = self._radar[channel] = self._radar_channel(channel)
            if token in frames:
                return frames[token]
        data, source = self.sensors.file_bytes(token, filename, "radar", where=True)  # embedded, else the file
        return radar_from_bytes(source, data)

    def _radar_channel(self, channel: str) -> dict[str, np.ndarray]:
        names = self.dataset.scan("radar_points").collect_schema().names()
        fields = [n for n in names if n not in POINTS_FRAME_COLUMNS and n != "passes_default_filters"]
        table = self.dataset.radar_points(scene=self.scene, channel=channel, columns=["sample_data_token", *fields])
        table = table.with_columns(pl.col("sample_data_token").cast(pl.String))
        return {key[0]: records({name: part[name].to_numpy() for name in fields})
                for key, part in table.partition_by("sample_data_token", as_dict=True, maintain_order=True).items()}
