"""The converter's transforms over arrays: sensor -> keyframe-lidar (`obtain_sensor2top`), annotation boxes into
a sensor frame (devkit `get_sample_data` / `Box.translate` + `Box.rotate`), velocities into a sensor frame, and
mmdetection3d's float32 4x4 (`convert_quaternion_to_matrix`). Same operations in the same order as the
converter, batched: `(N, ...)` arrays, one row per sensor reading or per box."""

from __future__ import annotations

import numpy as np

from nuparquet.index import quaternions
from nuparquet.index.blas import gemm, gemv_cols, gemv_rows, inv3


def _t(m: np.ndarray) -> np.ndarray:
    return np.swapaxes(m, -1, -2)


def sensor_to_lidar(sensor_t, sensor_q, sensor_ego_t, sensor_ego_q, lidar_t, lidar_q, ego_t, ego_q):
    """`obtain_sensor2top`: (R (N, 3, 3), T (N, 3)) with points_lidar = points_sensor @ R.T + T.

    sensor_*: the reading's calibration (translation, rotation); sensor_ego_*: its ego pose; lidar_*, ego_*:
    the keyframe lidar's calibration and ego pose (one row per reading). Returns `sensor2lidar_rotation`
    (= R.T of the converter's R) and `sensor2lidar_translation`.
    """
    l2e_r_s = quaternions.rotation_matrices(sensor_q)
    e2g_r_s = quaternions.rotation_matrices(sensor_ego_q)
    e2g_inv = inv3(quaternions.rotation_matrices(ego_q))
    l2e_inv = inv3(quaternions.rotation_matrices(lidar_q))
    back = gemm(_t(e2g_inv), _t(l2e_inv))
    r = gemm(gemm(_t(l2e_r_s), _t(e2g_r_s)), back)
    # `x @ M.T` of a C-ordered M is numpy's gemv of M and x (gemv_rows); `x @ back` is gemv_cols
    t = gemv_cols(gemv_rows(e2g_r_s, np.asarray(sensor_t, np.float64)) + sensor_ego_t, back)
    t = t - (gemv_cols(np.asarray(ego_t, np.float64), back) + gemv_rows(l2e_inv, np.asarray(lidar_t, np.float64)))
    return _t(r), t


def sensor_from_lidar_f32(sensor2lidar_r: np.ndarray, sensor2lidar_t: np.ndarray, *, f32: bool = True) -> np.ndarray:
    """(N, 4, 4) `lidar2cam` / `lidar2sensor` of update_infos_to_v2: [R.T, -R.T @ T], rounded to float32."""
    rt = _t(sensor2lidar_r)
    out = np.zeros(rt.shape[:-2] + (4, 4))
    out[..., :3, :3] = rt
    out[..., :3, 3] = -gemv_rows(rt, sensor2lidar_t)  # -1 * np.matmul(rot.T, trans.reshape(3, 1))
    out[..., 3, 3] = 1.0
    return out.astype(np.float32) if f32 else out


def pose_matrix_f32(q: np.ndarray, t: np.ndarray, *, f32: bool = True) -> np.ndarray:
    """(N, 4, 4) `convert_quaternion_to_matrix(q, t)`: rotation and translation, rounded to float32."""
    out = np.zeros(np.shape(q)[:-1] + (4, 4))
    out[..., :3, :3] = quaternions.rotation_matrices(q)
    out[..., :3, 3] = t
    out[..., 3, 3] = 1.0
    return out.astype(np.float32) if f32 else out


def boxes_to_sensor(center, rotation, ego_t, ego_q, sensor_t, sensor_q):
    """Global boxes into a sensor frame as the devkit moves a Box: (center (N, 3), orientation (N, 4)).

    Each step is `translate(-t)` then `rotate(inverse q)`; `rotate` normalises the inverse quaternion
    (rotation_matrix does, in place) before multiplying the orientation by it.
    """
    center = np.asarray(center, np.float64)
    orientation = np.asarray(rotation, np.float64)
    for t, q in ((ego_t, ego_q), (sensor_t, sensor_q)):
        q_inv = quaternions.normalised(quaternions.inverse(q))
        center = gemv_rows(quaternions.rotation_matrices(q_inv), center - t)
        orientation = quaternions.multiply(q_inv, orientation)
    return center, orientation


def velocity_to_sensor(velocity_xy: np.ndarray, ego_q: np.ndarray, sensor_q: np.ndarray) -> np.ndarray:
    """(N, 3) [vx, vy, 0] @ inv(e2g).T @ inv(s2e).T: a global xy velocity into a sensor frame (NaN stays NaN)."""
    v = np.concatenate([velocity_xy, np.zeros(velocity_xy.shape[:-1] + (1,))], axis=-1)
    v = gemv_rows(inv3(quaternions.rotation_matrices(ego_q)), v)
    return gemv_rows(inv3(quaternions.rotation_matrices(sensor_q)), v)


def box_corners(center, size_wlh, orientation) -> np.ndarray:
    """(N, 3, 8) devkit `Box.corners()`: corners in the box's frame rotated by the orientation, then moved."""
    w, l, h = np.moveaxis(np.asarray(size_wlh, np.float64), -1, 0)
    x = (l / 2)[:, None] * np.array([1, 1, 1, 1, -1, -1, -1, -1])
    y = (w / 2)[:, None] * np.array([1, -1, -1, 1, 1, -1, -1, 1])
    z = (h / 2)[:, None] * np.array([1, 1, -1, -1, 1, 1, -1, -1])
    local = np.stack([x, y, z], axis=1)  # (N, 3, 8)
    r = quaternions.rotation_matrices(orientation)
    return gemm(r, local) + center[:, :, None]
