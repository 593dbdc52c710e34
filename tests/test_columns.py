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
