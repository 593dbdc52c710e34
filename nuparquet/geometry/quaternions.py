"""Quaternions `[..., 4]` in `[w, x, y, z]` order (the nuScenes JSON order), vectorised, with pyquaternion's
semantics reproduced exactly (its unit tolerance, its Pade fast normalisation, its slerp), so results can be
checked against the devkit, which uses pyquaternion throughout. numpy only.

pyquaternion's |q|^2 and q0 . q1 are `np.dot` of 4-vectors, i.e. the machine's BLAS `ddot`, whose rounding
depends on the CPU's kernel; they are computed here through the same routine (`dots.rowwise_dot`), so the
branches they decide (already unit? the shorter arc? linear or spherical?) are pyquaternion's on every machine.
"""

from __future__ import annotations

import numpy as np

from nuparquet.geometry.dots import rowwise_dot

# pyquaternion treats |q|^2 within this of 1 as already unit and leaves it untouched (Quaternion.is_unit).
_PYQUATERNION_UNIT_TOLERANCE = 1e-14
# pyquaternion's _fast_normalise uses a Pade approximation of the norm when |q|^2 is this close to 1.
_PYQUATERNION_PADE_LIMIT = 2.107342e-08
# pyquaternion's slerp falls back to normalised linear interpolation above this |cos(angle)|.
_PYQUATERNION_SLERP_LINEAR_DOT = 0.9995


def as_float_array(values, trailing: tuple[int, ...], name: str) -> np.ndarray:
    array = np.asarray(values, dtype=np.float64)
    if array.shape[array.ndim - len(trailing):] != trailing:
        raise ValueError(f"{name} must have shape (..., {', '.join(map(str, trailing))}), got {array.shape}")
    return array


def normalise_quaternions(q_wxyz) -> np.ndarray:
    """Unit quaternions, as pyquaternion's `Quaternion._normalise` makes them.

    Args:
        q_wxyz: (..., 4) quaternions [w, x, y, z], any non-zero norm.

    Returns:
        (..., 4) float64: each quaternion divided by its norm, except those pyquaternion already considers
        unit (|q|^2 within 1e-14 of 1), which are returned unchanged; zero quaternions stay zero.
    """
    q = as_float_array(q_wxyz, (4,), "q_wxyz")
    norm_squared = rowwise_dot(q, q)[..., None]
    already_unit = np.abs(1.0 - norm_squared) < _PYQUATERNION_UNIT_TOLERANCE
    norm = np.sqrt(norm_squared)
    keep = already_unit | (norm == 0.0)
    return np.where(keep, q, q / np.where(keep, 1.0, norm))


def _fast_normalise_quaternions(q: np.ndarray) -> np.ndarray:
    """pyquaternion's `_fast_normalise`, vectorised: (..., 4) -> (..., 4).

    slerp uses this approximation (not `_normalise`), so interpolated rotations only agree with the devkit's
    to the last bits if we reproduce it.
    """
    norm_squared = rowwise_dot(q, q)[..., None]
    error = np.abs(1.0 - norm_squared)
    magnitude = np.where(error < _PYQUATERNION_PADE_LIMIT, (1.0 + norm_squared) / 2.0, np.sqrt(norm_squared))
    keep = (error < _PYQUATERNION_UNIT_TOLERANCE) | (norm_squared == 0.0)
    return np.where(keep, q, q / np.where(keep, 1.0, magnitude))


def rotation_matrices(q_wxyz) -> np.ndarray:
    """Rotation matrices of quaternions, the numbers of pyquaternion's `Quaternion(q).rotation_matrix`.

    Args:
        q_wxyz: (..., 4) quaternions [w, x, y, z]; normalised first, as pyquaternion does.

    Returns:
        (..., 3, 3) float64 rotation matrices R with `v_rotated = R @ v`.
    """
    w, x, y, z = np.moveaxis(normalise_quaternions(q_wxyz), -1, 0)
    # The same products pyquaternion forms (Q(q) @ Qbar(q)^T): the diagonal keeps all four squares rather
    # than 1 - 2(...), so the results agree to rounding for every input, not only for exact unit quaternions.
    rows = [
        [w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ]
    matrices = np.empty(w.shape + (3, 3))
    for i, row in enumerate(rows):
        for j, value in enumerate(row):
            matrices[..., i, j] = value
    return matrices


def quaternion_slerp(q0_wxyz, q1_wxyz, amount) -> np.ndarray:
    """Spherical linear interpolation with pyquaternion's `Quaternion.slerp(q0, q1, amount)` semantics.

    Those semantics, reproduced bit for bit where possible: both ends are normalised with pyquaternion's fast
    (Pade) normalisation; `amount` is clipped to [0, 1]; when q0 . q1 < 0 *q0* is negated so the shorter arc is
    taken; when q0 . q1 > 0.9995 the result is normalised linear interpolation; the result is fast-normalised.

    Args:
        q0_wxyz: (N, 4) start quaternions [w, x, y, z] (amount 0).
        q1_wxyz: (N, 4) end quaternions (amount 1).
        amount: (N,) or scalar interpolation parameter.

    Returns:
        (N, 4) float64 interpolated unit quaternions.
    """
    q0 = _fast_normalise_quaternions(as_float_array(q0_wxyz, (4,), "q0_wxyz"))
    q1 = _fast_normalise_quaternions(as_float_array(q1_wxyz, (4,), "q1_wxyz"))
    amount = np.clip(np.asarray(amount, dtype=np.float64), 0.0, 1.0)[..., None]
    dot = rowwise_dot(q0, q1)[..., None]  # pyquaternion's np.dot: its sign picks the arc
    q0 = np.where(dot < 0.0, -q0, q0)
    dot = np.abs(dot)

    linear = q0 + amount * (q1 - q0)

    # Only evaluated where the arc is long enough for sin(theta_0) to be safely non-zero.
    arc = dot <= _PYQUATERNION_SLERP_LINEAR_DOT
    theta_0 = np.arccos(np.where(arc, dot, 0.0))
    sin_theta_0 = np.sin(theta_0)
    theta = theta_0 * amount
    sin_theta = np.sin(theta)
    safe_sin_theta_0 = np.where(arc, sin_theta_0, 1.0)
    s0 = np.cos(theta) - dot * sin_theta / safe_sin_theta_0
    s1 = sin_theta / safe_sin_theta_0
    spherical = s0 * q0 + s1 * q1

    return _fast_normalise_quaternions(np.where(arc, spherical, linear))


def invert_quaternions(q_wxyz) -> np.ndarray:
    """(..., 4) pyquaternion's `Quaternion(q).inverse`: the conjugate over |q|^2 (a unit quaternion's conjugate)."""
    q = as_float_array(q_wxyz, (4,), "q_wxyz")
    return q * np.array([1.0, -1.0, -1.0, -1.0]) / np.sum(q * q, axis=-1, keepdims=True)


def multiply_quaternions(p_wxyz, q_wxyz) -> np.ndarray:
    """(..., 4) Hamilton products p * q (rotate by q first, then p), as pyquaternion's `p * q`; broadcasts."""
    p = as_float_array(p_wxyz, (4,), "p_wxyz")
    q = as_float_array(q_wxyz, (4,), "q_wxyz")
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def yaw_from_quaternions(q_wxyz) -> np.ndarray:
    """Yaw angles as pyquaternion's `Quaternion(q).yaw_pitch_roll[0]`.

    For rotations about z only (every nuScenes box and ego pose, to rounding) this equals the devkit's
    `quaternion_yaw` and `heading_from_quaternions`; for tilted rotations pyquaternion's z-y'-x'' convention
    differs from the heading of the rotated x axis.

    Args:
        q_wxyz: (..., 4) quaternions [w, x, y, z]; normalised first, as pyquaternion does.

    Returns:
        (...,) float64 yaw in radians, in [-pi, pi].
    """
    w, x, y, z = np.moveaxis(normalise_quaternions(q_wxyz), -1, 0)
    return np.arctan2(2.0 * (w * z - x * y), 1.0 - 2.0 * (y * y + z * z))


def heading_from_quaternions(q_wxyz) -> np.ndarray:
    """Heading of the rotated x axis in the xy plane, as devkit `geometry_utils.quaternion_yaw`.

    Args:
        q_wxyz: (..., 4) quaternions [w, x, y, z].

    Returns:
        (...,) float64 angle in radians, in [-pi, pi], of R @ [1, 0, 0] projected onto the xy plane.
    """
    rotation = rotation_matrices(q_wxyz)
    return np.arctan2(rotation[..., 1, 0], rotation[..., 0, 0])


def vehicle_flat_from_vehicle(q_wxyz) -> np.ndarray:
    """(..., 3, 3) the devkit's `rotation_vehicle_flat_from_vehicle` of ego orientations (`render_sample_data` with
    `use_flat_vehicle_coordinates=True`): the rotation about z by the yaw (`yaw_from_quaternions`) times the inverse
    of the full rotation, R_z(yaw) @ R^T. The identity for an upright ego; for a tilted one this is the devkit's
    arithmetic (it takes the tilt inverted and turned by the yaw), kept so that its top views are reproduced."""
    yaw = yaw_from_quaternions(q_wxyz)
    half = yaw / 2.0
    z_rotation = rotation_matrices(np.stack([np.cos(half), np.zeros_like(half), np.zeros_like(half), np.sin(half)],
                                            axis=-1))
    return z_rotation @ np.swapaxes(rotation_matrices(q_wxyz), -1, -2)
