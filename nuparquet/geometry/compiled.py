"""The compiled kernels of `geometry` (numba), loaded on first use; numpy's versions stay the reference.

`pair_kernel()` returns the fused (pair, corner) projection of `geometry.box_projection`, or None when numba
cannot load (not installed, a numpy it does not support, no compiler for this CPU), after one warning that says
why and that the numpy path is used. The kernel repeats the numpy columns' arithmetic operation for operation
(no fast-math: no reassociation, no fused multiply-add), so both give the same bits; tests hold them to it.

Compiled code is cached beside this file (numba's `cache=True`, or its per-user cache where that folder is
read-only): a process pays the ~1 s compilation once per machine, then ~0.1 s to load it.
"""

from __future__ import annotations

import warnings

import numpy as np

from nuparquet.geometry.boxes import _CORNER_SIGNS_XYZ
from nuparquet.geometry.projection import CORNER_MIN_DEPTH_M, NEAR_PLANE_M

_KERNELS: dict[str, object] = {}
_FAILED: list[str] = []


class KernelUnavailable(RuntimeWarning):
    """numba could not load: the numpy implementation runs instead (same results, slower on big batches)."""


def pair_kernel():
    """The compiled pair projection, or None (with one KernelUnavailable warning per process)."""
    if "pairs" in _KERNELS:
        return _KERNELS["pairs"]
    if _FAILED:
        return None
    try:
        _KERNELS["pairs"] = _build_pair_kernel()
    except Exception as exc:  # noqa: BLE001 - any failure to import or compile means: use numpy
        _FAILED.append(f"{type(exc).__name__}: {exc}")
        warnings.warn(f"nuparquet: the compiled geometry kernel is unavailable ({_FAILED[0]}); using numpy "
                      "(same results, slower on large batches). `pip install numba` brings it back.",
                      KernelUnavailable, stacklevel=3)
        return None
    return _KERNELS["pairs"]


def _build_pair_kernel():
    import numba

    # error_model="numpy": x / 0 gives inf/nan as numpy does (a corner at depth 0), not ZeroDivisionError.
    options = {"error_model": "numpy", "nogil": True, "boundscheck": False}
    try:
        return numba.njit(cache=True, **options)(project_pairs)
    except RuntimeError:  # no writable cache folder anywhere ("no locator available"): compile in each process
        return numba.njit(**options)(project_pairs)


# Module globals are frozen into the compiled kernel as constants.
_SIGNS = np.ascontiguousarray(_CORNER_SIGNS_XYZ)
_NEAR_M = float(NEAR_PLANE_M)
_MIN_DEPTH_M = float(CORNER_MIN_DEPTH_M)


def project_pairs(frame, axes_row, translation, half_axes, ego_rotation, ego_translation, camera_rotation,
                  camera_translation, global_to_camera, intrinsic, low_px, high_px,
                  center_ego, center_camera, corners, corners_px, corner_visible, in_front, visible, distance):
    """The kernel (plain Python here; `pair_kernel` compiles it): `box_projection._numpy_pairs`' arithmetic per
    pair, writing only the outputs (the arguments after `high_px`, allocated by the caller).

    Written out in scalars: a camera's 40 terms are loaded once per run of pairs of the same camera (pairs come
    grouped by frame) and stay in registers; small arrays or inner loops cost ~3x the instructions."""
    last = -1
    e00 = e01 = e02 = e10 = e11 = e12 = e20 = e21 = e22 = et0 = et1 = et2 = 0.0
    c00 = c01 = c02 = c10 = c11 = c12 = c20 = c21 = c22 = ct0 = ct1 = ct2 = 0.0
    g00 = g01 = g02 = g10 = g11 = g12 = g20 = g21 = g22 = 0.0
    k00 = k01 = k02 = k10 = k11 = k12 = k20 = k21 = k22 = 0.0
    lu = lv = hu = hv = 0.0
    for m in range(frame.shape[0]):
        f = frame[m]
        if f != last:
            last = f
            e00, e01, e02 = ego_rotation[f, 0, 0], ego_rotation[f, 0, 1], ego_rotation[f, 0, 2]
            e10, e11, e12 = ego_rotation[f, 1, 0], ego_rotation[f, 1, 1], ego_rotation[f, 1, 2]
            e20, e21, e22 = ego_rotation[f, 2, 0], ego_rotation[f, 2, 1], ego_rotation[f, 2, 2]
            et0, et1, et2 = ego_translation[f, 0], ego_translation[f, 1], ego_translation[f, 2]
            c00, c01, c02 = camera_rotation[f, 0, 0], camera_rotation[f, 0, 1], camera_rotation[f, 0, 2]
            c10, c11, c12 = camera_rotation[f, 1, 0], camera_rotation[f, 1, 1], camera_rotation[f, 1, 2]
            c20, c21, c22 = camera_rotation[f, 2, 0], camera_rotation[f, 2, 1], camera_rotation[f, 2, 2]
            ct0, ct1, ct2 = camera_translation[f, 0], camera_translation[f, 1], camera_translation[f, 2]
            g00, g01, g02 = global_to_camera[f, 0, 0], global_to_camera[f, 0, 1], global_to_camera[f, 0, 2]
            g10, g11, g12 = global_to_camera[f, 1, 0], global_to_camera[f, 1, 1], global_to_camera[f, 1, 2]
            g20, g21, g22 = global_to_camera[f, 2, 0], global_to_camera[f, 2, 1], global_to_camera[f, 2, 2]
            k00, k01, k02 = intrinsic[f, 0, 0], intrinsic[f, 0, 1], intrinsic[f, 0, 2]
            k10, k11, k12 = intrinsic[f, 1, 0], intrinsic[f, 1, 1], intrinsic[f, 1, 2]
            k20, k21, k22 = intrinsic[f, 2, 0], intrinsic[f, 2, 1], intrinsic[f, 2, 2]
            lu, lv, hu, hv = low_px[f, 0], low_px[f, 1], high_px[f, 0], high_px[f, 1]
        t0, t1, t2 = translation[m, 0], translation[m, 1], translation[m, 2]
        x0 = ((e00 * t0 + e01 * t1) + e02 * t2) + et0
        x1 = ((e10 * t0 + e11 * t1) + e12 * t2) + et1
        x2 = ((e20 * t0 + e21 * t1) + e22 * t2) + et2
        y0 = ((c00 * x0 + c01 * x1) + c02 * x2) + ct0
        y1 = ((c10 * x0 + c11 * x1) + c12 * x2) + ct1
        y2 = ((c20 * x0 + c21 * x1) + c22 * x2) + ct2
        center_ego[m, 0], center_ego[m, 1], center_ego[m, 2] = x0, x1, x2
        center_camera[m, 0], center_camera[m, 1], center_camera[m, 2] = y0, y1, y2
        h = axes_row[m]
        h00, h01, h02 = half_axes[h, 0, 0], half_axes[h, 0, 1], half_axes[h, 0, 2]
        h10, h11, h12 = half_axes[h, 1, 0], half_axes[h, 1, 1], half_axes[h, 1, 2]
        h20, h21, h22 = half_axes[h, 2, 0], half_axes[h, 2, 1], half_axes[h, 2, 2]
        # axis j in the camera, component r: (h_j0 g_r0 + h_j1 g_r1) + h_j2 g_r2
        a00 = (h00 * g00 + h01 * g01) + h02 * g02
        a01 = (h00 * g10 + h01 * g11) + h02 * g12
        a02 = (h00 * g20 + h01 * g21) + h02 * g22
        a10 = (h10 * g00 + h11 * g01) + h12 * g02
        a11 = (h10 * g10 + h11 * g11) + h12 * g12
        a12 = (h10 * g20 + h11 * g21) + h12 * g22
        a20 = (h20 * g00 + h21 * g01) + h22 * g02
        a21 = (h20 * g10 + h21 * g11) + h22 * g12
        a22 = (h20 * g20 + h21 * g21) + h22 * g22
        all_front = True
        any_visible = False
        for k in range(8):
            s0, s1, s2 = _SIGNS[k, 0], _SIGNS[k, 1], _SIGNS[k, 2]
            x = ((s0 * a00 + s1 * a10) + s2 * a20) + y0
            y = ((s0 * a01 + s1 * a11) + s2 * a21) + y1
            z = ((s0 * a02 + s1 * a12) + s2 * a22) + y2
            corners[m, k, 0], corners[m, k, 1], corners[m, k, 2] = x, y, z
            p0 = (x * k00 + y * k01) + z * k02
            p1 = (x * k10 + y * k11) + z * k12
            p2 = (x * k20 + y * k21) + z * k22
            u = p0 / p2
            v = p1 / p2
            corners_px[m, k, 0], corners_px[m, k, 1] = u, v
            seen = (u > lu) & (u < hu) & (v > lv) & (v < hv) & (z > _MIN_DEPTH_M)
            corner_visible[m, k] = seen
            any_visible |= seen
            all_front &= z > _NEAR_M
        in_front[m] = all_front
        visible[m] = any_visible & all_front
        distance[m] = np.sqrt((y0 * y0 + y1 * y1) + y2 * y2)
