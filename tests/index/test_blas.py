"""The element-by-element BLAS replay (nuparquet/index/blas.py) against exact rational arithmetic and numpy.

Bit-equality with numpy 1.26 + OpenBLAS is what tests/index/test_reference.py checks on the real extract;
here: the emulated FMA rounds exactly once (Fractions), and the products/inverse are the right mathematics
(a transposed operand, a swapped pivot or a dropped term would be far off)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from nuparquet.index.replay import blas


def test_fma_rounds_once():
    rng = np.random.default_rng(7)
    a = rng.normal(size=4000) * 10.0 ** rng.integers(-6, 6, 4000)
    b = rng.normal(size=4000) * 10.0 ** rng.integers(-6, 6, 4000)
    c = -(a * b) * (1 + rng.normal(size=4000) * 1e-13) + rng.normal(size=4000) * rng.integers(0, 2, 4000)
    got = blas.fma(a, b, c)
    exact = [float(Fraction(x) * Fraction(y) + Fraction(z)) for x, y, z in zip(a, b, c)]
    assert got.tolist() == exact
    # and it differs from the two-rounding a * b + c somewhere (else the test would prove nothing)
    assert (got != a * b + c).any()


def test_products_and_inverse_are_the_right_mathematics():
    rng = np.random.default_rng(8)
    a, b = rng.normal(size=(500, 3, 3)), rng.normal(size=(500, 3, 8))
    q, x = rng.normal(size=(500, 4, 4)), rng.normal(size=(500, 4))
    v = rng.normal(size=(500, 3))
    np.testing.assert_allclose(blas.gemm(a, b), np.einsum("nij,njk->nik", a, b), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(blas.gemv_rows(a, v), np.einsum("nij,nj->ni", a, v), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(blas.gemv_rows(q, x), np.einsum("nij,nj->ni", q, x), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(blas.gemv_cols(v, a), np.einsum("nj,nji->ni", v, a), rtol=1e-12, atol=1e-12)
    inv = blas.inv3(a)
    np.testing.assert_allclose(np.einsum("nij,njk->nik", inv, a), np.broadcast_to(np.eye(3), a.shape), atol=1e-9)
    # a matrix that needs both row swaps
    m = np.array([[0.0, 1.0, 2.0], [0.0, 0.0, 3.0], [4.0, 5.0, 6.0]])
    np.testing.assert_allclose(blas.inv3(m[None])[0], np.linalg.inv(m), rtol=1e-15)
