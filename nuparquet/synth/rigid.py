"""Quaternions, rigid transforms and cuboid corners for the generator (numpy only, vectorised over N).

A deliberate second implementation: the generator is a producer of nuScenes data like any real dataset, and the
tests compare what nuparquet computes from its output with what the generator drew. Sharing
`nuparquet.geometry` here would make those comparisons circular, so this module re-implements the few formulas
it needs from their textbook forms (and pyquaternion's slerp), independently.

Conventions are nuScenes': quaternions are [w, x, y, z] and map the child frame into the parent frame
(`ego_from_sensor`), boxes are (center, [width, length, height], rotation) with corners in the devkit's
`Box.corners()` order. The interpolation between keyframes reproduces the devkit's `get_boxes` (linear centre,
pyquaternion slerp), so painted sweep images agree with what the devkit computes."""

from __future__ import annotations

import numpy as np


def quat_from_yaw(yaw_rad: np.ndarray) -> np.ndarray:
    """(N,) yaw about +z -> (N, 4) unit quaternions [w, x, y, z]."""
    half = 0.5 * np.asarray(yaw_rad, dtype=np.float64)
    out = np.zeros(half.shape + (4,))
    out[..., 0] = np.cos(half)
    out[..., 3] = np.sin(half)
    return out


def quat_from_axis_angle(axis: tuple[float, float, float], angle_rad: np.ndarray) -> np.ndarray:
    """Rotation by (N,) angles about one fixed unit axis -> (N, 4)."""
    half = 0.5 * np.asarray(angle_rad, dtype=np.float64)
    out = np.zeros(half.shape + (4,))
    out[..., 0] = np.cos(half)
    out[..., 1:] = np.sin(half)[..., None] * np.asarray(axis, dtype=np.float64)
    return out


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of (..., 4) quaternions (the rotation b first, then a)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def quat_from_matrix(rotation: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix -> (4,) unit quaternion with w >= 0."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.asarray(q)
    q = q / np.linalg.norm(q)
    return -q if q[0] < 0 else q


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions -> (..., 3, 3) rotation matrices (normalised first, as pyquaternion does)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def quat_slerp(q0: np.ndarray, q1: np.ndarray, amount: np.ndarray) -> np.ndarray:
    """(N, 4), (N, 4), (N,) -> (N, 4): pyquaternion's `Quaternion.slerp`, which the devkit uses to interpolate
    sweep boxes (short path; linear blend when the quaternions are within ~1.8 degrees)."""
    q0 = q0 / np.linalg.norm(q0, axis=-1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    amount = np.clip(np.asarray(amount, dtype=np.float64), 0.0, 1.0)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q0 = np.where(dot < 0.0, -q0, q0)
    dot = np.abs(dot)
    linear = q0 + amount * (q1 - q0)
    linear = linear / np.linalg.norm(linear, axis=-1, keepdims=True)
    theta_0 = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta_0 = np.where(dot > 0.9995, 1.0, np.sin(theta_0))  # guarded: the linear branch is used there
    theta = theta_0 * amount
    s1 = np.sin(theta) / sin_theta_0
    s0 = np.cos(theta) - dot * s1
    spherical = s0 * q0 + s1 * q1
    spherical = spherical / np.linalg.norm(spherical, axis=-1, keepdims=True)
    return np.where(dot > 0.9995, linear, spherical)


def box_corners(center: np.ndarray, wlh: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(N, 3) centres, (N, 3) [width, length, height], (N, 4) quaternions -> (N, 8, 3) corners in the centres'
    frame, in the devkit's `Box.corners()` order (first four: the front face, +x of the box)."""
    signs_x = np.array([1, 1, 1, 1, -1, -1, -1, -1], dtype=np.float64)
    signs_y = np.array([1, -1, -1, 1, 1, -1, -1, 1], dtype=np.float64)
    signs_z = np.array([1, 1, -1, -1, 1, 1, -1, -1], dtype=np.float64)
    half_w, half_l, half_h = (0.5 * wlh).T
    corners_box = np.stack([half_l[:, None] * signs_x, half_w[:, None] * signs_y, half_h[:, None] * signs_z],
                           axis=-1)  # (N, 8, 3) in the box frame
    frame_from_box = quat_to_matrix(rotation)  # (N, 3, 3)
    return np.einsum("nij,nkj->nki", frame_from_box, corners_box) + center[:, None, :]


def transform_points(dst_from_src: np.ndarray, points_src: np.ndarray) -> np.ndarray:
    """Apply a (4, 4) rigid transform to (..., 3) points."""
    return points_src @ dst_from_src[:3, :3].T + dst_from_src[:3, 3]


def rigid_matrix(translation: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(3,) translation and (4,) quaternion of `parent_from_child` -> (4, 4) matrix."""
    parent_from_child = np.eye(4)
    parent_from_child[:3, :3] = quat_to_matrix(np.asarray(rotation, dtype=np.float64))
    parent_from_child[:3, 3] = translation
    return parent_from_child


def invert_rigid(parent_from_child: np.ndarray) -> np.ndarray:
    """(4, 4) rigid transform -> its inverse `child_from_parent`."""
    child_from_parent = np.eye(4)
    rotation_t = parent_from_child[:3, :3].T
    child_from_parent[:3, :3] = rotation_t
    child_from_parent[:3, 3] = -rotation_t @ parent_from_child[:3, 3]
    return child_from_parent
