"""`nuparquet.devkit.columns.fixed_block`: fixed-size list columns as (N, k) / (N, k, m) numpy blocks, also for a
chunked column of no chunks (an empty table read back) and of several chunks."""

from __future__ import annotations

import numpy as np
import pyarrow as pa

from nuparquet.devkit.columns import fixed_block


def test_fixed_block_keeps_the_shape_of_an_empty_or_chunked_column():
    row = pa.list_(pa.float64(), 3)
    assert fixed_block(pa.chunked_array([], type=row)).shape == (0, 3)
    assert fixed_block(pa.chunked_array([], type=pa.list_(row, 2))).shape == (0, 2, 3)
    chunks = pa.chunked_array([pa.array([[1.0, 2.0, 3.0]], row), pa.array([[4.0, 5.0, 6.0]], row)])
    np.testing.assert_array_equal(fixed_block(chunks), [[1, 2, 3], [4, 5, 6]])
