"""The topics of a scene's MCAP file, each a `Stream`: its topic, schema, message times and an `encode(i)` that
builds message i only when it is written (images and points are read one at a time, never all held).

Topics (Foxglove schemas unless said otherwise; `CHANNEL` is each channel of the data):
- `/tf` foxglove.FrameTransforms, one per sample_data: `map` -> `base_link` (the ego pose at that frame's time)
  and `base_link` -> `CHANNEL` (the sensor's calibration);
- `/CHANNEL/image_rect_compressed` foxglove.CompressedImage (the JPEG as stored) and `/CHANNEL/camera_info`
  foxglove.CameraCalibration, one per camera frame;
- `/CHANNEL` foxglove.PointCloud, one per lidar and radar frame (sensor frame);
- `/markers/annotations` foxglove.SceneUpdate, the boxes at each keyframe and, with `boxes="camera"`, at every
  frame of the default camera in between (interpolated as the devkit's get_boxes);
- `/map` foxglove.SceneUpdate, once at the scene's first time: the map layers around the route;
- `/can_bus/<message>` JSON (with a JSON Schema), one per CAN bus message, every field plottable.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from nuparquet import columns
from nuparquet.frames.boxes import frame_boxes
from nuparquet.mcap import messages
from nuparquet.mcap.points import PointReader
from nuparquet.sensors.reader import MissingSensorData, inside
from nuparquet.mcap.scene import SceneRows
from nuparquet.rendering.palette import category_rgb
from nuparquet.geometry.quaternions import normalise_quaternions

TF_TOPIC = "/tf"
BOXES_TOPIC = "/markers/annotations"
MAP_TOPIC = "/map"
BOX_ALPHA = 0.5


class MissingFile(Exception):
    """A sensor file a message needs is missing or unreadable (`path`, `reason`)."""

    def __init__(self, path: str, reason: str):
        super().__init__(f"{path}: {reason}")
        self.path = path
        self.reason = reason


@dataclass(frozen=True)
class Stream:
    """One topic: `schema` is a protobuf message class, or (name, JSON Schema dict) for JSON messages; message i
    is at `times_us[i]` and is built by `encode(i)` (which raises MissingFile when its file cannot be read)."""

    topic: str
    schema: Any
    times_us: np.ndarray
    encode: Callable[[int], bytes]
    reads_bytes: Callable[[int], int] | None = None  # size of the sensor file message i carries (for the summary)

    def __len__(self) -> int:
        return len(self.times_us)


def image_path(dataroot: Path | None, filename: str) -> Path:
    """Where a frame's file is named in messages about it (under the dataroot; the filename itself when the output
    embeds its files and no dataroot is known)."""
    if dataroot is None:
        return Path(filename)
    path = inside(dataroot, filename)
    if path is None:
        raise MissingFile(str(dataroot / filename), "outside the dataroot: refused")
    return path


def sensor_file(sensors, dataroot: Path | None, token: str, filename: str, modality: str) -> bytes:
    """The bytes of a frame's file through the dataset's sensor reader (embedded, else under the dataroot);
    MissingFile when it cannot be read."""
    path = image_path(dataroot, filename)
    try:
        return sensors.file_bytes(token, filename, modality)
    except MissingSensorData:
        raise MissingFile(str(path), "no such file") from None
    except OSError as exc:
        raise MissingFile(str(path), exc.strerror or type(exc).__name__) from None


def transform_stream(frames: pl.DataFrame) -> Stream:
    """`/tf`: per frame, map -> base_link (ego pose) and base_link -> channel (calibration), the stored poses with
    their quaternions normalised (the stored matrices were built from them the same way)."""
    times = frames["timestamp"].to_numpy()
    channel = frames["channel"].to_list()
    ego_t = columns.to_numpy(frames["ego_translation"], (3,))
    ego_q = normalise_quaternions(columns.to_numpy(frames["ego_rotation"], (4,)))
    sensor_t = columns.to_numpy(frames["sensor_translation"], (3,))
    sensor_q = normalise_quaternions(columns.to_numpy(frames["sensor_rotation"], (4,)))

    def encode(i: int) -> bytes:
        return messages.frame_transforms(int(times[i]), [
            (messages.MAP_FRAME, messages.EGO_FRAME, ego_t[i], ego_q[i]),
            (messages.EGO_FRAME, channel[i], sensor_t[i], sensor_q[i]),
        ])

    return Stream(TF_TOPIC, FrameTransforms, times, encode)


def camera_streams(frames: pl.DataFrame, channel: str, sensors, dataroot: Path | None, *,
                   images: bool) -> list[Stream]:
    """`/CHANNEL/camera_info` and (with `images`) `/CHANNEL/image_rect_compressed` of one camera's frames."""
    times = frames["timestamp"].to_numpy()
    width, height = frames["width"].to_numpy(), frames["height"].to_numpy()
    intrinsic = columns.to_numpy(frames["camera_intrinsic"], (3, 3))
    filenames = frames["filename"].to_list()

    def calibration(i: int) -> bytes:
        return messages.camera_calibration(int(times[i]), channel, int(width[i]), int(height[i]), intrinsic[i])

    streams = [Stream(f"/{channel}/camera_info", CameraCalibration, times, calibration)]
    if images:
        tokens = frames["token"].to_list()

        def image(i: int) -> bytes:
            data = sensor_file(sensors, dataroot, tokens[i], filenames[i], "camera")
            suffix = Path(filenames[i]).suffix.lower().lstrip(".")
            image_format = "jpeg" if suffix in ("jpg", "jpeg") else suffix
            return messages.compressed_image(int(times[i]), channel, data, image_format)

        def size(i: int) -> int:
            return sensors.file_size(tokens[i], filenames[i], "camera")

        streams.append(Stream(f"/{channel}/image_rect_compressed", CompressedImage, times, image, size))
    return streams


def point_stream(frames: pl.DataFrame, channel: str, modality: str, dataroot: Path | None,
                 reader: PointReader) -> Stream:
    """`/CHANNEL`: one foxglove.PointCloud per lidar or radar frame, in the sensor frame."""
    times = frames["timestamp"].to_numpy()
    tokens, filenames = frames["token"].to_list(), frames["filename"].to_list()

    def encode(i: int) -> bytes:
        path = image_path(dataroot, filenames[i])
        try:
            records = (reader.lidar(tokens[i], filenames[i]) if modality == "lidar"
                       else reader.radar(tokens[i], channel, filenames[i]))
        except MissingSensorData:
            raise MissingFile(str(path), "not converted, and no such file") from None
        except (OSError, ValueError) as exc:  # PointFileError (truncated, not a PCD), an unreadable file
            raise MissingFile(str(path), getattr(exc, "reason", None) or getattr(exc, "strerror", None)
                              or type(exc).__name__) from None
        return messages.point_cloud(int(times[i]), channel, records)

    def size(i: int) -> int:
        return reader.sensors.file_size(tokens[i], filenames[i], modality)

    return Stream(f"/{channel}", PointCloud, times, encode, size)


def box_frames(rows: SceneRows, camera: str | None, rate: str) -> pl.DataFrame:
    """The times the boxes are published, as frames for `frame_boxes`: every sample (a keyframe, its
    annotations as they are) and, with rate "camera", every non-keyframe of `camera` (interpolated), by time."""
    keyframes = rows.samples.select("token", pl.col("token").alias("sample_token"), "timestamp",
                                    pl.lit(True).alias("is_key_frame"))
    parts = [keyframes]
    if rate == "camera" and camera is not None:
        parts.append(rows.frames.filter((pl.col("channel") == camera) & ~pl.col("is_key_frame"))
                     .select("token", "sample_token", "timestamp", "is_key_frame"))
    return pl.concat(parts).sort("timestamp", "is_key_frame", "token", descending=[False, True, False])


def box_stream(rows: SceneRows, camera: str | None, rate: str) -> Stream:
    """`/markers/annotations`: one SceneUpdate per box time (`box_frames`), the boxes of `frame_boxes` (the devkit's
    `get_boxes`: annotations at keyframes, interpolated between them), each replacing the previous update."""
    frames = box_frames(rows, camera, rate)
    boxes = frame_boxes(frames, rows.annotations, rows.samples)
    times = frames["timestamp"].to_numpy()
    bounds = np.searchsorted(boxes.frame_index, np.arange(len(frames) + 1))
    palette = {name: (*(c / 255 for c in category_rgb(name)), BOX_ALPHA) for name in set(boxes.category_name.tolist())}
    rgba = np.array([palette[name] for name in boxes.category_name], dtype=np.float64).reshape(-1, 4)

    def encode(i: int) -> bytes:
        s = slice(bounds[i], bounds[i + 1])
        return messages.box_update(int(times[i]), boxes.instance_token[s], boxes.category_name[s],
                                   boxes.annotation_token[s], boxes.translation_m[s], boxes.size_wlh_m[s],
                                   boxes.rotation_wxyz[s], rgba[s], boxes.interpolated[s])

    return Stream(BOXES_TOPIC, SceneUpdate, times, encode)


def map_stream(time_us: int, layers: list[tuple]) -> Stream:
    """`/map`: one SceneUpdate at `time_us` holding every map layer (`map_layers.map_layers_near`)."""
    return Stream(MAP_TOPIC, SceneUpdate, np.array([time_us], dtype=np.int64),
                  lambda i: messages.map_update(time_us, layers))


def json_schema(dtype: pl.DataType) -> dict:
    """The JSON Schema of a polars column's values as `write_ndjson` writes them."""
    if dtype.is_integer():
        return {"type": "integer"}
    if dtype.is_float():
        return {"type": ["number", "null"]}  # NaN is written as null
    if dtype == pl.Boolean:
        return {"type": "boolean"}
    if isinstance(dtype, (pl.Array, pl.List)):
        return {"type": "array", "items": json_schema(dtype.inner)}
    if isinstance(dtype, pl.Struct):
        return {"type": "object", "properties": {f.name: json_schema(f.dtype) for f in dtype.fields}}
    return {"type": "string"}


def can_bus_stream(message: str, rows: pl.DataFrame) -> Stream:
    """`/can_bus/<message>`: one JSON object per CAN bus message (every field; `utime` its time, microseconds)."""
    schema = {"title": f"nuScenes CAN bus {message}", "type": "object",
              "properties": {name: json_schema(dtype) for name, dtype in rows.schema.items()}}
    lines = rows.write_ndjson().encode().splitlines() if rows.height else []
    return Stream(f"/can_bus/{message}", (f"nuscenes.can_bus.{message}", schema), rows["utime"].to_numpy(),
                  lambda i: lines[i])
