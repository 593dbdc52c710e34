"""The converter's small matrix products, element by element, in the order and rounding numpy 1.26 + OpenBLAS
(its Haswell/Zen kernels, what mmdetection3d's reference output was computed with) perform them, so that
the infos equal the reference bit for bit on any machine: BLAS calls on the machine running the index would
use whatever kernel its CPU selects (AVX-512 kernels sum in another order).

Established against numpy 1.26.4 with `OPENBLAS_CORETYPE=Haswell` on random inputs (27,000 values per
operation, every bit equal):
- `gemm` (`A @ B`, `np.dot` of matrices, any transposition): per element, fused multiply-adds over k in order.
- `gemv_rows` (`A @ x`, `np.dot(A, x)`, `x @ A.T`: the `dgemv_t` kernel): 3 terms as
  fma(a2, x2, fma(a0, x0, a1 * x1)); 4 terms as (p0 + p2) + (p1 + p3).
- `gemv_cols` (`x @ A` with a C-ordered A: `dgemv_n`): plain products summed left to right.
- `inv3` (`np.linalg.inv`: `dgesv` = `getf2` LU with partial pivoting, then two `trsm` with inverted diagonals).
- `np.dot(q, q)` of 4-vectors (`ddot`): plain products summed left to right (`quaternions._sum4`).
All arrays are float64 with any leading batch shape `(...)`.
"""

from __future__ import annotations

import numpy as np

_SPLIT = 134217729.0  # 2**27 + 1 (Veltkamp splitting of a float64 into two 26-bit halves)


def _two_product(a, b):
    """(p, e) with p + e == a * b exactly (Dekker)."""
    p = a * b
    c = _SPLIT * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLIT * b
    bh = c - (c - b)
    bl = b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _two_sum(a, b):
    """(s, e) with s + e == a + b exactly (Knuth)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def fma(a, b, c) -> np.ndarray:
    """round(a * b + c) with one rounding, like the FMA instruction (numpy has none): Boldo & Melquiond's
    emulation, the exact product's low part added with rounding to odd before the final rounding. Exact
    unless a product overflows or underflows (|a| or |b| beyond ~1e150, or subnormal parts), which poses,
    boxes and intrinsics never approach."""
    uh, ul = _two_product(np.asarray(a, np.float64), np.asarray(b, np.float64))
    th, tl = _two_sum(np.asarray(c, np.float64), uh)
    s, err = _two_sum(tl, ul)
    s = np.asarray(s)
    even = (s.view(np.int64) & 1) == 0
    s = np.where((err != 0) & even, np.nextafter(s, np.where(err > 0, np.inf, -np.inf)), s)
    return th + s


def gemm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., m, n) a @ b for (..., m, k) a and (..., k, n) b."""
    acc = a[..., :, 0, None] * b[..., None, 0, :]
    for k in range(1, a.shape[-1]):
        acc = fma(a[..., :, k, None], b[..., None, k, :], acc)
    return acc


def gemv_rows(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(..., m) a @ x for (..., m, 3) or (..., m, 4) a and (..., 3|4) x."""
    x = x[..., None, :]
    if a.shape[-1] == 3:
        return fma(a[..., 2], x[..., 2], fma(a[..., 0], x[..., 0], a[..., 1] * x[..., 1]))
    p = a * x
    return (p[..., 0] + p[..., 2]) + (p[..., 1] + p[..., 3])


def gemv_cols(x: np.ndarray, a: np.ndarray) -> np.ndarray:
    """(..., 3) x @ a for (..., 3) x and (..., 3, 3) a (a row vector times a matrix)."""
    return (x[..., 0, None] * a[..., 0, :] + x[..., 1, None] * a[..., 1, :]) + x[..., 2, None] * a[..., 2, :]


def _swap_rows(m: np.ndarray, row: int, other: np.ndarray) -> None:
    """In place: swap row `row` with row `other[i]` of each matrix i of (N, 3, k) m."""
    n = np.arange(len(m))
    top = m[n, row].copy()
    m[n, row] = m[n, other]
    m[n, other] = top


def inv3(matrices: np.ndarray) -> np.ndarray:
    """(..., 3, 3) np.linalg.inv. Singular matrices give inf/nan instead of raising (the converter's
    rotation matrices never are)."""
    shape = matrices.shape
    lu = np.array(matrices, np.float64).reshape(-1, 3, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        # getf2, left-looking: pivot on the largest magnitude (first of equals), multipliers times 1/pivot
        pivot0 = np.argmax(np.abs(lu[:, :, 0]), axis=1)
        _swap_rows(lu, 0, pivot0)
        lu[:, 1:, 0] *= (1.0 / lu[:, 0, 0])[:, None]
        lu[:, 1:, 1] = lu[:, 1:, 1] - lu[:, 1:, 0] * lu[:, 0, 1, None]
        pivot1 = 1 + np.argmax(np.abs(lu[:, 1:, 1]), axis=1)
        _swap_rows(lu, 1, pivot1)
        lu[:, 2, 1] *= 1.0 / lu[:, 1, 1]
        lu[:, 1, 2] = lu[:, 1, 2] - lu[:, 1, 0] * lu[:, 0, 2]
        lu[:, 2, 2] = lu[:, 2, 2] - (lu[:, 2, 0] * lu[:, 0, 2] + lu[:, 2, 1] * lu[:, 1, 2])
        # getrs on the identity: forward with unit L (last row through the gemm kernel), back with 1/diag
        rhs = np.broadcast_to(np.eye(3), lu.shape).copy()
        _swap_rows(rhs, 0, pivot0)
        _swap_rows(rhs, 1, pivot1)
        y0 = rhs[:, 0]
        y1 = rhs[:, 1] - y0 * lu[:, 1, 0, None]
        y2 = rhs[:, 2] - fma(lu[:, 2, 1, None], y1, lu[:, 2, 0, None] * y0)
        x2 = y2 * (1.0 / lu[:, 2, 2])[:, None]
        x1 = (y1 - lu[:, 1, 2, None] * x2) * (1.0 / lu[:, 1, 1])[:, None]
        x0 = ((y0 - lu[:, 0, 2, None] * x2) - x1 * lu[:, 0, 1, None]) * (1.0 / lu[:, 0, 0])[:, None]
    return np.stack([x0, x1, x2], axis=1).reshape(shape)
