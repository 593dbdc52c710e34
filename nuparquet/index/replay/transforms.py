"""The converter's transforms over arrays: sensor -> keyframe-lidar (`obtain_sensor2top`), annotation boxes into
a sensor frame (devkit `get_sample_data` / `Box.translate` + `Box.rotate`), velocities into a sensor frame, and
mmdetection3d's float32 4x4 (`convert_quaternion_to_matrix`). Same operations in the same order as the
converter, batched: `(N, ...)` arrays, one row per sensor reading or per box."""

from __future__ import annotations

import numpy as np

from nuparquet.index.replay import quaternions
from nuparquet.index.replay.blas import gemm, gemv_cols, gemv_rows, inv3


def _t(m: np.ndarray) -> np.ndarray:
    return np.swapaxes(m, -1, -2)


def _per_reading(reading: np.ndarray, matrices_of) -> np.ndarray:
    """`matrices_of(rows)` computed once per distinct reading and gathered for every row of `reading`: the
    rotation matrices and inverses of a camera's pose are shared by all of its boxes."""
    unique, index = np.unique(reading, return_inverse=True)
    return matrices_of(unique)[index]


def sensor_to_lidar(rows, lidar_rows, sensor_t, sensor_q, ego_t, ego_q):
    """`obtain_sensor2top`: (R (N, 3, 3), T (N, 3)) with points_lidar = points_sensor @ R.T + T.

    rows (N,): the readings; lidar_rows (N,): the keyframe lidar reading of each; sensor_* (calibration) and
    ego_* (ego pose): (D, ...) per reading. Returns `sensor2lidar_rotation` (= R.T of the converter's R) and
    `sensor2lidar_translation`.
    """
    l2e_r_s = _per_reading(rows, lambda r: quaternions.rotation_matrices(sensor_q[r]))
    e2g_r_s = _per_reading(rows, lambda r: quaternions.rotation_matrices(ego_q[r]))

    def lidar_side(r):  # (inv(e2g_r_mat).T @ inv(l2e_r_mat).T, inv(l2e_r_mat)) per keyframe lidar reading
        e2g_inv = inv3(quaternions.rotation_matrices(ego_q[r]))
        l2e_inv = inv3(quaternions.rotation_matrices(sensor_q[r]))
        return np.stack([gemm(_t(e2g_inv), _t(l2e_inv)), l2e_inv], axis=1)

    back, l2e_inv = np.moveaxis(_per_reading(lidar_rows, lidar_side), 1, 0)
    r = gemm(gemm(_t(l2e_r_s), _t(e2g_r_s)), back)
    # `x @ M.T` of a C-ordered M is numpy's gemv of M and x (gemv_rows); `x @ back` is gemv_cols
    t = gemv_cols(gemv_rows(e2g_r_s, sensor_t[rows]) + ego_t[rows], back)
    t = t - (gemv_cols(ego_t[lidar_rows], back) + gemv_rows(l2e_inv, sensor_t[lidar_rows]))
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


def boxes_to_sensor(center, rotation, reading, ego_t, ego_q, sensor_t, sensor_q):
    """Global boxes into the frame of sensor reading `reading` (N,) as the devkit moves a Box: (center (N, 3),
    orientation (N, 4)). `ego_*`, `sensor_*`: (D, ...) per reading.

    Each step is `translate(-t)` then `rotate(inverse q)`; `rotate` normalises the inverse quaternion
    (rotation_matrix does, in place) before multiplying the orientation by it.
    """
    center = np.asarray(center, np.float64)
    orientation = np.asarray(rotation, np.float64)
    for t, q in ((ego_t, ego_q), (sensor_t, sensor_q)):
        q_inv = quaternions.normalised(quaternions.inverse(q[reading]))
        r = _per_reading(reading, lambda rows, q=q: quaternions.rotation_matrices(
            quaternions.normalised(quaternions.inverse(q[rows]))))
        center = gemv_rows(r, center - t[reading])
        orientation = quaternions.multiply(q_inv, orientation)
    return center, orientation


def rough_boxes_to_sensor(center, rotation, reading, ego_t, ego_q, sensor_t, sensor_q):
    """`boxes_to_sensor` with plain float products (centres within ~1e-12 relative of the exact ones; the
    orientation is exact): for pre-filters with margins only."""
    center = np.asarray(center, np.float64)
    orientation = np.asarray(rotation, np.float64)
    for t, q in ((ego_t, ego_q), (sensor_t, sensor_q)):
        r = _per_reading(reading, lambda rows, q=q: quaternions.rough_rotation_matrices(q[rows]))
        center = np.einsum("nji,nj->ni", r, center - t[reading])  # R.T @ (c - t)
        orientation = quaternions.multiply(quaternions.normalised(quaternions.inverse(q[reading])), orientation)
    return center, orientation


def velocity_to_sensor(velocity_xy: np.ndarray, reading: np.ndarray, ego_q: np.ndarray,
                       sensor_q: np.ndarray) -> np.ndarray:
    """(N, 3) [vx, vy, 0] @ inv(e2g).T @ inv(s2e).T: a global xy velocity into the frame of sensor reading
    `reading` (N,); `ego_q`, `sensor_q` (D, 4) per reading. NaN stays NaN."""
    v = np.concatenate([velocity_xy, np.zeros(velocity_xy.shape[:-1] + (1,))], axis=-1)
    for q in (ego_q, sensor_q):
        v = gemv_rows(_per_reading(reading, lambda rows, q=q: inv3(quaternions.rotation_matrices(q[rows]))), v)
    return v


def box_local_corners(size_wlh) -> np.ndarray:
    """(N, 3, 8) devkit `Box.corners()` before rotation: x = l/2 * (1, 1, 1, 1, -1, -1, -1, -1), and so on."""
    w, l, h = np.moveaxis(np.asarray(size_wlh, np.float64), -1, 0)
    x = (l / 2)[:, None] * np.array([1, 1, 1, 1, -1, -1, -1, -1])
    y = (w / 2)[:, None] * np.array([1, -1, -1, 1, 1, -1, -1, 1])
    z = (h / 2)[:, None] * np.array([1, 1, -1, -1, 1, 1, -1, -1])
    return np.stack([x, y, z], axis=1)


def box_corners(center, size_wlh, orientation) -> np.ndarray:
    """(N, 3, 8) devkit `Box.corners()`: corners in the box's frame rotated by the orientation, then moved."""
    # corners 4-7 are corners 2, 3, 0, 1 negated (before the move) and rounding is symmetric: half the products
    half = gemm(quaternions.rotation_matrices(orientation), box_local_corners(size_wlh)[:, :, :4])
    return np.concatenate([half, -half[:, :, [2, 3, 0, 1]]], axis=2) + center[:, :, None]
