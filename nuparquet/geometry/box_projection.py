"""Boxes into camera images in one pass over (box, camera) pairs: each box's centre moved global -> ego ->
camera, its corners built in the camera from its half-axes, projected, and tested as the devkit's `box_in_image`
tests them.

Two implementations of the same arithmetic, operation for operation and in the same order, so they give the same
bits: numpy over columns (here: small batches, and wherever numba cannot load) and a compiled kernel over
(pair, corner) that writes only the outputs (`geometry.compiled`, numba: large batches). Which one runs is
`kernel=` ("auto": the compiled one from `COMPILED_MIN_PAIRS` pairs on, when numba loads; the environment
variable NUPARQUET_KERNEL=numpy|compiled|auto overrides the default for a whole process).

The arithmetic (devkit `get_sample_data` + `view_points` + `box_in_image`), sums of three taken left to right:

    centre_ego = E t + e          (E, e: the frame's ego_from_global; t: the box centre, global)
    centre_cam = C centre_ego + c (C, c: the frame's camera_from_ego)
    axis_j     = G h_j            (G = C E, once per frame; h_j: the box's half-axis j, global)
    corner_k   = (s_k0 axis_0 + s_k1 axis_1 + s_k2 axis_2) + centre_cam   (s: `Box.corners()` signs, +-1)
    p = K corner_k;  u, v = p_0 / p_2, p_1 / p_2;  depth = corner_k z
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from nuparquet.geometry.boxes import _CORNER_SIGNS_XYZ
from nuparquet.geometry.camera import Cameras
from nuparquet.geometry.projection import CORNER_MIN_DEPTH_M, NEAR_PLANE_M

# Below this many pairs the numpy columns win: loading numba and the cached kernel costs ~0.3 s, what numpy
# spends on ~150k pairs.
COMPILED_MIN_PAIRS = 100_000
KERNELS = ("auto", "numpy", "compiled")
NUMPY_CHUNK = 4096  # pairs per pass of the numpy columns


@dataclass(frozen=True)
class PairsInImages:
    """M (box, camera) pairs projected.

    center_ego_m, center_camera_m: (M, 3); corners_camera_m: (M, 8, 3) in `Box.corners()` order; corners_px:
    (M, 8, 2) [u, v] (a corner behind the camera projects mirrored, one at depth 0 to inf/nan, as in the devkit);
    depths: (M, 8) camera z of the corners (a view of corners_camera_m); corner_visible: (M, 8) inside the
    full-size image and deeper than 1 m; in_front: (M,) every corner deeper than 0.1 m; visible: (M,) some corner
    visible and in front (BoxVisibility.ANY); distance_m: (M,) |centre_cam|.
    """

    center_ego_m: np.ndarray
    center_camera_m: np.ndarray
    corners_camera_m: np.ndarray
    corners_px: np.ndarray
    corner_visible: np.ndarray
    in_front: np.ndarray
    visible: np.ndarray
    distance_m: np.ndarray

    @property
    def depths(self) -> np.ndarray:
        return self.corners_camera_m[..., 2]


@dataclass(frozen=True)
class FrameTerms:
    """Per camera (F rows), the terms every pair of that camera uses, computed once with numpy (both
    implementations read these same numbers): rotations and translations of ego_from_global (E, e) and
    camera_from_ego (C, c), G = C E, the intrinsics K, and the open pixel bounds of the full-size image in the
    camera's own pixels (`pixels_in_image` with no margin): low < u < high."""

    ego_rotation: np.ndarray  # (F, 3, 3)
    ego_translation: np.ndarray  # (F, 3)
    camera_rotation: np.ndarray  # (F, 3, 3)
    camera_translation: np.ndarray  # (F, 3)
    global_to_camera: np.ndarray  # (F, 3, 3)
    intrinsic: np.ndarray  # (F, 3, 3)
    low_px: np.ndarray  # (F, 2)
    high_px: np.ndarray  # (F, 2)

    @classmethod
    def of(cls, cameras: Cameras) -> FrameTerms:
        c = np.ascontiguousarray
        ego_rotation = c(cameras.ego_from_global[:, :3, :3], dtype=np.float64)
        camera_rotation = c(cameras.camera_from_ego[:, :3, :3], dtype=np.float64)
        scale = np.asarray(cameras.scale, dtype=np.float64)
        offset = (scale - 1.0) / 2.0  # where the full image's pixel 0 lands (projection.scale_pixels)
        return cls(ego_rotation, c(cameras.ego_from_global[:, :3, 3], dtype=np.float64), camera_rotation,
                   c(cameras.camera_from_ego[:, :3, 3], dtype=np.float64), c(camera_rotation @ ego_rotation),
                   c(cameras.image_from_camera, dtype=np.float64), c(0.0 * scale + offset),
                   c(np.asarray(cameras.size_px, dtype=np.float64) - 0.0 * scale + offset))


def project_pairs(cameras: Cameras, frame_index, translation_m, half_axes, axes_index, *,
                  kernel: str | None = None) -> PairsInImages:
    """Project M (box, camera) pairs.

    Args:
        cameras: F cameras (`Cameras`); frame_index: (M,) the camera of each pair.
        translation_m: (M, 3) each pair's box centre in the global frame, metres.
        half_axes: (K, 3, 3) half-axes in the global frame (`boxes.box_half_axes`), one row per distinct box
            (an annotation seen by six cameras is one row); axes_index: (M,) each pair's row of `half_axes`.
        kernel: "auto", "numpy" or "compiled" (None: NUPARQUET_KERNEL, else "auto"). "compiled" falls back to
            numpy, with a warning saying why, when numba cannot load.
    """
    frame_index = np.ascontiguousarray(frame_index, dtype=np.int64)
    axes_index = np.ascontiguousarray(axes_index, dtype=np.int64)
    translation_m = np.ascontiguousarray(translation_m, dtype=np.float64).reshape(-1, 3)
    half_axes = np.ascontiguousarray(half_axes, dtype=np.float64).reshape(-1, 3, 3)
    terms = FrameTerms.of(cameras)
    out = _allocate(len(frame_index))
    if _use_compiled(kernel, len(frame_index)):
        from nuparquet.geometry import compiled

        project = compiled.pair_kernel()
        if project is not None:
            project(frame_index, axes_index, translation_m, half_axes, terms.ego_rotation, terms.ego_translation,
                    terms.camera_rotation, terms.camera_translation, terms.global_to_camera, terms.intrinsic,
                    terms.low_px, terms.high_px, *_fields(out))
            return out
    for start in range(0, len(frame_index), NUMPY_CHUNK):  # temporaries of a chunk stay in the CPU's cache
        rows = slice(start, start + NUMPY_CHUNK)
        _numpy_pairs(frame_index[rows], axes_index[rows], translation_m[rows], half_axes, terms,
                     PairsInImages(*(field[rows] for field in _fields(out))))
    return out


def _use_compiled(kernel: str | None, pairs: int) -> bool:
    kernel = kernel or os.environ.get("NUPARQUET_KERNEL") or "auto"
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {', '.join(KERNELS)}, got {kernel!r}")
    return kernel == "compiled" or (kernel == "auto" and pairs >= COMPILED_MIN_PAIRS)


def _allocate(m: int) -> PairsInImages:
    return PairsInImages(np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 8, 3)), np.empty((m, 8, 2)),
                         np.empty((m, 8), dtype=bool), np.empty(m, dtype=bool), np.empty(m, dtype=bool),
                         np.empty(m))


def _fields(out: PairsInImages) -> tuple[np.ndarray, ...]:
    return (out.center_ego_m, out.center_camera_m, out.corners_camera_m, out.corners_px, out.corner_visible,
            out.in_front, out.visible, out.distance_m)


def _rotate(matrix: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(M, 3, 3) @ (M, 3) as (m_r0 v_0 + m_r1 v_1) + m_r2 v_2, the kernel's order."""
    return (matrix[:, :, 0] * v[:, 0:1] + matrix[:, :, 1] * v[:, 1:2]) + matrix[:, :, 2] * v[:, 2:3]


def _numpy_pairs(frame, axes_row, translation, half_axes, terms: FrameTerms, out: PairsInImages) -> None:
    """The kernel's arithmetic over columns (see the module docstring), into `out`."""
    center_ego = _rotate(terms.ego_rotation[frame], translation) + terms.ego_translation[frame]
    center_camera = _rotate(terms.camera_rotation[frame], center_ego) + terms.camera_translation[frame]
    g, h = terms.global_to_camera[frame], half_axes[axes_row]  # (M, 3, 3) each
    # axis[m, j, r] = (h_j0 g_r0 + h_j1 g_r1) + h_j2 g_r2
    axis = ((h[:, :, None, 0] * g[:, None, :, 0] + h[:, :, None, 1] * g[:, None, :, 1])
            + h[:, :, None, 2] * g[:, None, :, 2])
    s = _CORNER_SIGNS_XYZ
    corners = ((s[None, :, 0, None] * axis[:, None, 0, :] + s[None, :, 1, None] * axis[:, None, 1, :])
               + s[None, :, 2, None] * axis[:, None, 2, :]) + center_camera[:, None, :]
    k = terms.intrinsic[frame][:, None]  # (M, 1, 3, 3)
    p = ((corners[..., None, 0] * k[..., 0] + corners[..., None, 1] * k[..., 1])
         + corners[..., None, 2] * k[..., 2])  # (M, 8, 3): p_r = (x k_r0 + y k_r1) + z k_r2
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = p[..., :2] / p[..., 2:3]
    low, high = terms.low_px[frame][:, None], terms.high_px[frame][:, None]
    depth = corners[..., 2]
    inside = ((uv[..., 0] > low[..., 0]) & (uv[..., 0] < high[..., 0]) & (uv[..., 1] > low[..., 1])
              & (uv[..., 1] < high[..., 1]))
    out.center_ego_m[...] = center_ego
    out.center_camera_m[...] = center_camera
    out.corners_camera_m[...] = corners
    out.corners_px[...] = uv
    out.corner_visible[...] = inside & (depth > CORNER_MIN_DEPTH_M)
    out.in_front[...] = np.all(depth > NEAR_PLANE_M, axis=1)
    out.visible[...] = np.any(out.corner_visible, axis=1) & out.in_front
    x, y, z = center_camera[:, 0], center_camera[:, 1], center_camera[:, 2]
    out.distance_m[...] = np.sqrt((x * x + y * y) + z * z)
