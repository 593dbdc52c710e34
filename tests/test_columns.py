"""`nuparquet.columns.to_series`: an (N, *shape) array as a polars Array column, with `valid` marking the rows that
are null (the CAN bus vectors of samples without pose messages, projected boxes outside every camera)."""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.columns import to_series


def test_rows_not_valid_are_null_and_the_others_keep_their_values():
    values = np.arange(12, dtype=np.float64).reshape(3, 2, 2)
    series = to_series("m", values, valid=np.array([True, False, True]))
    assert series.name == "m" and series.dtype == pl.Array(pl.Float64, 4)
    assert series.to_list() == [[0.0, 1.0, 2.0, 3.0], None, [8.0, 9.0, 10.0, 11.0]]
    nested = to_series("m", values, nested=True, valid=np.array([False, True, True]))
    assert nested.dtype == pl.Array(pl.Float64, (2, 2)) and nested.to_list()[0] is None
    assert nested.to_list()[1] == [[4.0, 5.0], [6.0, 7.0]]
    assert to_series("m", values).null_count() == 0 and to_series("m", values, valid=np.ones(3, bool)).null_count() == 0


def test_to_numpy_gives_null_rows_as_nan_rows_in_the_row_shape():
    from nuparquet.columns import to_numpy

    column = pl.Series("m", [[1.0, 2.0, 3.0, 4.0], None, [5.0, 6.0, 7.0, 8.0]], dtype=pl.List(pl.Float64))
    out = to_numpy(column, (2, 2))
    assert out.shape == (3, 2, 2) and np.isnan(out[1]).all()
    np.testing.assert_array_equal(out[[0, 2]], [[[1, 2], [3, 4]], [[5, 6], [7, 8]]])


def test_to_numpy_names_the_column_when_rows_do_not_hold_the_shape():
    """A row of the wrong size is refused with the column, the row size expected and the values found, on the
    fixed-size path (an Array column) and the variable-list one."""
    import pytest

    from nuparquet.columns import to_numpy

    lists = pl.Series("rotation", [[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], dtype=pl.List(pl.Float64))
    with pytest.raises(ValueError) as error:
        to_numpy(lists, (4,))
    assert str(error.value) == "column 'rotation': expected 4 values per row, got 7 for 2 rows"
    fixed = pl.Series("translation", [[1.0, 2.0, 3.0]] * 2, dtype=pl.Array(pl.Float64, 3))
    with pytest.raises(ValueError) as error:
        to_numpy(fixed, (4,))
    assert str(error.value) == "column 'translation': expected 4 values per row, got 6 for 2 rows"


def test_to_numpy_of_variable_lists_gives_the_dtype_asked_for():
    """List columns take the exploding path (not the fixed-size buffer): the rows come back in `dtype`, float32
    or int32 alike, not in the float64 or int64 the column's values are read as."""
    from nuparquet.columns import to_numpy

    floats = pl.Series("m", [[1.5, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.25]], dtype=pl.List(pl.Float64))
    out = to_numpy(floats, (2, 2), np.float32)
    assert out.dtype == np.float32 and out.shape == (2, 2, 2)
    np.testing.assert_array_equal(out, np.array([[[1.5, 2], [3, 4]], [[5, 6], [7, 8.25]]], dtype=np.float32))
    ints = pl.Series("k", [[1, 2, 3], [4, 5, 6]], dtype=pl.List(pl.Int64))
    out = to_numpy(ints, (3,), np.int32)
    assert out.dtype == np.int32 and out.tolist() == [[1, 2, 3], [4, 5, 6]]


def test_to_arrow_gives_fixed_size_lists_flat_or_one_level_per_axis_with_null_rows():
    """An (N, 2, 3) array as Arrow: flat, one list of 6 values a row; nested, lists of 2 lists of 3; a scalar
    per row, lists of 1; `valid` False rows null; float64 unless a value type is given."""
    import pyarrow as pa

    from nuparquet.columns import to_arrow

    values = np.arange(12, dtype=np.float64).reshape(2, 2, 3)
    flat = to_arrow(values)
    assert flat.type == pa.list_(pa.float64(), 6)
    assert flat.to_pylist() == [[0.0, 1.0, 2.0, 3.0, 4.0, 5.0], [6.0, 7.0, 8.0, 9.0, 10.0, 11.0]]
    nested = to_arrow(values, nested=True)
    assert nested.type == pa.list_(pa.list_(pa.float64(), 3), 2)
    assert nested.to_pylist() == [[[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]], [[6.0, 7.0, 8.0], [9.0, 10.0, 11.0]]]
    scalars = to_arrow(np.array([3, 4]), value_type=pa.int32())
    assert scalars.type == pa.list_(pa.int32(), 1) and scalars.to_pylist() == [[3], [4]]
    masked = to_arrow(values, valid=np.array([False, True]))
    assert masked.type == pa.list_(pa.float64(), 6) and masked.to_pylist() == [None, list(range(6, 12))]
