"""`DIR/infos/`: the v2 infos as Parquet, one row per keyframe sample, the same fields as nested columns
(documented in `schemas/index/infos.json`), so a loader reads one row at a time instead of unpickling the
whole list. Extra columns beside the converter's fields: `split`, and the corrected forms (`*_f64` matrices
before float32 rounding, `velocity_valid`)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pyarrow as pa

from nuparquet.index.records import NUM_PTS_FEATS
from nuparquet.index.v2_arrays import V2Arrays, gather_segments


def schema_doc() -> dict:
    packaged = resources.files("nuparquet") / "_schemas" / "index" / "infos.json"
    path = Path(str(packaged)) if packaged.is_file() else Path(__file__).resolve().parents[2] / "schemas" / "index" / "infos.json"
    return json.loads(path.read_text())


def _offsets(offsets: np.ndarray) -> pa.Array:
    return pa.array(np.asarray(offsets, np.int32))


def _lists(offsets: np.ndarray, values: pa.Array) -> pa.Array:
    return pa.ListArray.from_arrays(_offsets(offsets), values)


def _vectors(a: np.ndarray) -> pa.Array:
    """(N, k) -> list<float64>."""
    n, k = a.shape
    return _lists(np.arange(0, n * k + 1, k), pa.array(np.ascontiguousarray(a, np.float64).ravel()))


def _matrices(a: np.ndarray) -> pa.Array:
    """(..., r, c) -> list<list<float64>>, one matrix per row (leading axes flattened)."""
    r, c = a.shape[-2:]
    rows = _vectors(np.reshape(a, (-1, c)))
    return _lists(np.arange(0, len(rows) + 1, r), rows)


def _struct(**fields: pa.Array) -> pa.StructArray:
    return pa.StructArray.from_arrays(list(fields.values()), names=list(fields))


def _strings(a) -> pa.Array:
    return pa.array(a, type=pa.string())


def _per_camera(cameras: tuple[str, ...], column) -> pa.StructArray:
    """struct<camera: ...> from `column(k)`, the Arrow array of camera k over all samples."""
    return _struct(**{cam: column(k) for k, cam in enumerate(cameras)})


def infos_table(v: V2Arrays, split: str) -> pa.Table | None:
    """The split's rows as one Arrow table, built from the same arrays as the pickle's entries (None for an
    empty split)."""
    s = len(v.token)
    if s == 0:
        return None
    n_cam = len(v.cameras)
    cam_path = np.asarray(v.cam_path, dtype=object).reshape(s, n_cam)
    images = _per_camera(v.cameras, lambda k: _struct(
        img_path=_strings(cam_path[:, k]), cam2img=_matrices(v.cam2img[:, k]), cam2ego=_matrices(v.cam2ego[:, k]),
        sample_data_token=_strings(v.cam_token[:, k]), timestamp=pa.array(v.cam_timestamp_s[:, k]),
        lidar2cam=_matrices(v.lidar2cam[:, k])))
    lidar_points = _struct(num_pts_feats=pa.array(np.full(s, NUM_PTS_FEATS, np.int64)),
                           lidar_path=_strings(v.lidar_path), lidar2ego=_matrices(v.lidar2ego))
    w = len(v.sweep_token)
    sweeps = _lists(v.sweep_offsets, _struct(
        timestamp=pa.array(v.sweep_timestamp_s, pa.float64()), ego2global=_matrices(v.sweep_ego2global),
        lidar_points=_struct(num_pts_feats=pa.nulls(w), lidar_path=_strings(v.sweep_path),
                             lidar2ego=_matrices(v.sweep_lidar2ego), lidar2sensor=_matrices(v.sweep_lidar2sensor)),
        sample_data_token=_strings(v.sweep_token)))
    instances = _lists(v.ann_offsets, _struct(
        bbox_label=pa.array(v.ann_label, pa.int64()), bbox_3d=_vectors(v.ann_box),
        bbox_3d_isvalid=pa.array(v.ann_valid, pa.bool_()), bbox_label_3d=pa.array(v.ann_label, pa.int64()),
        num_lidar_pts=pa.array(v.ann_num_lidar_pts, pa.int64()), num_radar_pts=pa.array(v.ann_num_radar_pts, pa.int64()),
        velocity=_vectors(v.ann_velocity), velocity_valid=pa.array(np.isfinite(v.ann_velocity).all(axis=1))))
    if v.ci_offsets is not None:
        k_all = len(v.ci_label)
        ci = _struct(
            bbox_label=pa.array(v.ci_label, pa.int64()), bbox_label_3d=pa.array(v.ci_label, pa.int64()),
            bbox=_vectors(v.ci_bbox), bbox_3d_isvalid=pa.array(np.ones(k_all, bool)), bbox_3d=_vectors(v.ci_bbox_3d),
            velocity=_vectors(v.ci_velocity), center_2d=_vectors(v.ci_center_2d),
            depth=pa.array(v.ci_depth, pa.float64()), attr_label=pa.array(v.ci_attr_label, pa.int64()))

        def camera_lists(k):  # the camera-k segments of the sample-major instances
            picked, offsets = gather_segments(v.ci_offsets, np.arange(s) * n_cam + k)
            return _lists(offsets, ci.take(pa.array(picked, pa.int64())))

        cam_instances = _per_camera(v.cameras, camera_lists)
    else:  # test splits: no annotations, an empty list per camera
        cam_instances = _per_camera(v.cameras, lambda k: pa.array([[]] * s, pa.list_(pa.null())))
    columns = dict(
        sample_idx=pa.array(np.arange(s, dtype=np.int64)), token=_strings(v.token),
        timestamp=pa.array(v.timestamp_s, pa.float64()), ego2global=_matrices(v.ego2global), images=images,
        lidar_points=lidar_points, lidar_sweeps=sweeps, instances=instances,
        pts_semantic_mask_path=_strings([None] * s if v.semantic_mask_path is None else v.semantic_mask_path),
        cam_instances=cam_instances,
        split=_strings([split] * s), ego2global_f64=_matrices(v.ego2global_f64), lidar2ego_f64=_matrices(v.lidar2ego_f64))
    names = [c["name"] for c in schema_doc()["columns"]]
    return pa.table({name: columns[name] for name in names})
