"""Foxglove messages (the published `foxglove` protobuf schemas, `foxglove-schemas-protobuf`) built from arrays.

Each function returns the serialised message. Conventions (those of the devkit and of nuScenes' own
`nuscenes2mcap`): frames are named `map` (the global frame), `base_link` (the ego vehicle) and the channel
(`CAM_FRONT`, `LIDAR_TOP`, ...); a transform's parent is the frame it is expressed in (`map` -> `base_link` is
`global_from_ego`, `base_link` -> `LIDAR_TOP` is `ego_from_sensor`); quaternions are stored `[w, x, y, z]` and
written as Foxglove's (x, y, z, w); timestamps are the data's microseconds, exactly (sec + nanos).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

MAP_FRAME = "map"
EGO_FRAME = "base_link"
US_PER_S = 1_000_000

# numpy scalar type -> Foxglove PackedElementField numeric type (64-bit integers have none: written as float64).
_NUMERIC_TYPES = {
    np.dtype("u1"): PackedElementField.UINT8, np.dtype("i1"): PackedElementField.INT8,
    np.dtype("<u2"): PackedElementField.UINT16, np.dtype("<i2"): PackedElementField.INT16,
    np.dtype("<u4"): PackedElementField.UINT32, np.dtype("<i4"): PackedElementField.INT32,
    np.dtype("<f4"): PackedElementField.FLOAT32, np.dtype("<f8"): PackedElementField.FLOAT64,
}


def _stamp(timestamp, time_us: int) -> None:
    """Set a google.protobuf.Timestamp to `time_us` microseconds (floor division: exact for times before 1970)."""
    seconds, micros = divmod(int(time_us), US_PER_S)
    timestamp.seconds = seconds
    timestamp.nanos = micros * 1000


def _quaternion(target, q_wxyz) -> None:
    target.w, target.x, target.y, target.z = (float(v) for v in q_wxyz)


def _vector(target, xyz) -> None:
    target.x, target.y, target.z = (float(v) for v in xyz)


def _color(target, rgba) -> None:
    target.r, target.g, target.b, target.a = (float(v) for v in rgba)


def compressed_image(time_us: int, frame_id: str, data: bytes, image_format: str = "jpeg") -> bytes:
    """foxglove.CompressedImage of the file's bytes as they are (not re-encoded)."""
    message = CompressedImage(frame_id=frame_id, data=data, format=image_format)
    _stamp(message.timestamp, time_us)
    return message.SerializeToString()


def camera_calibration(time_us: int, frame_id: str, width: int, height: int, intrinsic) -> bytes:
    """foxglove.CameraCalibration of a pinhole camera without distortion (nuScenes' images are rectified): the
    plumb_bob model with zero coefficients, K the 3x3 intrinsic (row-major), R identity, P = [K | 0]."""
    K = np.asarray(intrinsic, dtype=np.float64).reshape(3, 3)
    message = CameraCalibration(frame_id=frame_id, width=int(width), height=int(height), distortion_model="plumb_bob",
                                D=[0.0] * 5, K=K.ravel().tolist(), R=np.eye(3).ravel().tolist(),
                                P=np.c_[K, np.zeros(3)].ravel().tolist())
    _stamp(message.timestamp, time_us)
    return message.SerializeToString()


def numeric_type(dtype: np.dtype) -> int:
    """The PackedElementField type of a numpy scalar type (ValueError for one Foxglove cannot hold)."""
    dtype = np.dtype(dtype).newbyteorder("<") if np.dtype(dtype).byteorder == ">" else np.dtype(dtype)
    if dtype not in _NUMERIC_TYPES:
        raise ValueError(f"no Foxglove point field type for {dtype}")
    return _NUMERIC_TYPES[dtype]


def point_cloud(time_us: int, frame_id: str, points: np.ndarray) -> bytes:
    """foxglove.PointCloud of (P,) structured points (packed little-endian fields, e.g. the PCD records as stored,
    or x, y, z, intensity, ring, labels): one PackedElementField per field, in the record's order and offsets,
    in the sensor's frame (identity pose)."""
    dtype = points.dtype
    message = PointCloud(frame_id=frame_id, point_stride=dtype.itemsize, data=np.ascontiguousarray(points).tobytes())
    _stamp(message.timestamp, time_us)
    message.pose.orientation.w = 1.0
    for name in dtype.names:
        field_type, offset = dtype.fields[name][:2]
        message.fields.add(name=name, offset=offset, type=numeric_type(field_type))
    return message.SerializeToString()


def frame_transforms(time_us: int, transforms: Sequence[tuple[str, str, np.ndarray, np.ndarray]]) -> bytes:
    """foxglove.FrameTransforms: each (parent, child, translation (3,) m, rotation (4,) [w, x, y, z]) is the pose of
    `child` expressed in `parent` (= the transform parent_from_child)."""
    message = FrameTransforms()
    for parent, child, translation, rotation in transforms:
        transform = message.transforms.add(parent_frame_id=parent, child_frame_id=child)
        _stamp(transform.timestamp, time_us)
        _vector(transform.translation, translation)
        _quaternion(transform.rotation, rotation)
    return message.SerializeToString()


def box_update(time_us: int, instance_token: Sequence[str], category_name: Sequence[str],
               annotation_token: Sequence[str], translation_m: np.ndarray, size_wlh_m: np.ndarray,
               rotation_wxyz: np.ndarray, colors_rgba: np.ndarray, interpolated: np.ndarray) -> bytes:
    """foxglove.SceneUpdate replacing every box of the topic by the B boxes given (global frame): one entity per
    box, its id the instance token (so a track keeps its entity), a cube (size x = length, y = width,
    z = height: the box frame is x forward as the devkit's `Box`), a text with the category above it, and the
    category, instance, annotation and whether it was interpolated as metadata.

    translation_m (B, 3), size_wlh_m (B, 3), rotation_wxyz (B, 4), colors_rgba (B, 4) in 0..1, interpolated (B,).
    """
    update = SceneUpdate()
    deletion = update.deletions.add(type=SceneEntityDeletion.ALL)
    _stamp(deletion.timestamp, time_us)
    for b in range(len(instance_token)):
        entity = update.entities.add(frame_id=MAP_FRAME, id=str(instance_token[b]))
        _stamp(entity.timestamp, time_us)
        cube = entity.cubes.add()
        _vector(cube.pose.position, translation_m[b])
        _quaternion(cube.pose.orientation, rotation_wxyz[b])
        width, length, height = (float(v) for v in size_wlh_m[b])
        cube.size.x, cube.size.y, cube.size.z = length, width, height
        _color(cube.color, colors_rgba[b])
        text = entity.texts.add(billboard=True, font_size=12.0, scale_invariant=True, text=str(category_name[b]))
        _vector(text.pose.position, (translation_m[b][0], translation_m[b][1], translation_m[b][2] + height / 2 + 0.5))
        text.pose.orientation.w = 1.0
        _color(text.color, (1.0, 1.0, 1.0, 1.0))
        for key, value in (("category", category_name[b]), ("instance_token", instance_token[b]),
                           ("annotation_token", annotation_token[b]),
                           ("interpolated", "true" if interpolated[b] else "false")):
            entity.metadata.add(key=key, value=str(value))
    return update.SerializeToString()


def map_update(time_us: int, layers: Sequence[tuple[str, str, np.ndarray, np.ndarray, tuple]]) -> bytes:
    """foxglove.SceneUpdate of the map: one entity per layer (id `map/<layer>`, frame `map`), never replaced.

    layers: (name, kind, points (K, 3) m, indices, rgba) with kind "triangles" (indices (T*3,): every three
    points a triangle) or "lines" (indices (S*2,): every two points a segment).
    """
    update = SceneUpdate()
    for name, kind, points, indices, rgba in layers:
        entity = update.entities.add(frame_id=MAP_FRAME, id=f"map/{name}")
        _stamp(entity.timestamp, time_us)
        entity.metadata.add(key="layer", value=name)
        primitive = (entity.triangles.add() if kind == "triangles"
                     else entity.lines.add(type=LinePrimitive.LINE_LIST, thickness=0.15, scale_invariant=False))
        primitive.pose.orientation.w = 1.0
        for x, y, z in np.asarray(points, dtype=np.float64).tolist():
            primitive.points.add(x=x, y=y, z=z)
        primitive.indices.extend(np.asarray(indices, dtype=np.int64).tolist())
        _color(primitive.color, rgba)
    return update.SerializeToString()
