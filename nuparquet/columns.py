"""The one bridge between Arrow/polars list columns and numpy arrays.

Vectors and matrices are stored as fixed-size lists (`schemas/`: translation `[3]`, rotation `[4]`, 4x4
transforms `[16]` and intrinsics `[9]`, row-major). Everything that needs them as numbers goes through
here: `to_numpy` turns a column into an `(N, *shape)` array, `to_series` / `to_arrow` turn an array back
into a column. No other module reshapes list columns by hand.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import polars as pl

if TYPE_CHECKING:  # pyarrow loads only where Arrow arrays are built (the converter): it costs ~30 MB and 0.1 s
    import pyarrow as pa

    Column = pl.Series | pa.Array | pa.ChunkedArray


def _is_arrow(column) -> bool:
    return type(column).__module__.split(".")[0] == "pyarrow"


def to_numpy(column: Column, shape: tuple[int, ...], dtype=np.float64, *, writable: bool = False) -> np.ndarray:
    """A (fixed-size or variable) list column as an `(N, *shape)` array of `dtype`.

    Without `writable` the array may be a read-only view of the column's buffer (no copy: a trainval frames
    batch holds hundreds of MB of matrices); with it, always a fresh copy.

    `shape` is the per-row shape: `(3,)` for translations, `(4, 4)` for a flattened `[16]` transform or a
    nested `[4][4]` one, `(3, 3)` for intrinsics. Null rows become NaN rows (use a float `dtype` then).

    Raises:
        ValueError: a non-null row does not hold `prod(shape)` values.
    """
    width = int(np.prod(shape))
    if _is_arrow(column):
        column = pl.Series(column.combine_chunks() if hasattr(column, "combine_chunks") else column)
    n = len(column)
    if n == 0:
        return np.zeros((0, *shape), dtype=dtype)
    if isinstance(column.dtype, pl.Array) and column.null_count() == 0:  # the fast path: one buffer
        values = column.to_numpy()
        if values.size != n * width:
            raise ValueError(f"column {column.name!r}: expected {width} values per row, got {values.size} for {n} rows")
        values = values.reshape((n, *shape)).astype(dtype, copy=False)
        return values.copy() if writable else values
    flat = column
    while flat.dtype in (pl.List, pl.Array) or isinstance(flat.dtype, (pl.List, pl.Array)):
        flat = flat.list.explode() if isinstance(flat.dtype, pl.List) else flat.arr.explode()
        if flat.dtype == pl.Null:
            break
    valid = column.is_not_null().to_numpy()
    values = flat.cast(pl.Float64 if np.issubdtype(np.dtype(dtype), np.floating) else flat.dtype).to_numpy()
    if valid.all():
        if values.size != n * width:
            raise ValueError(f"column {column.name!r}: expected {width} values per row, got {values.size} for {n} rows")
        return np.array(values, dtype=dtype).reshape((n, *shape))
    # explode() leaves one null per null row: keep only the values of valid rows.
    out = np.full((n, width), np.nan, dtype=dtype)
    kept = column.filter(column.is_not_null())
    if len(kept):
        out[valid] = to_numpy(kept, (width,), dtype)  # a fresh array: writable either way
    return out.reshape((n, *shape))


def to_arrow(values: np.ndarray, *, value_type: pa.DataType | None = None, nested: bool = False,
             valid: np.ndarray | None = None) -> pa.FixedSizeListArray:
    """An `(N, *shape)` array as a fixed-size-list Arrow array (flat, or with `nested` one level per axis; float64 unless `value_type`);
    `valid` (N,) marks the rows that are not null."""
    import pyarrow as pa

    value_type = pa.float64() if value_type is None else value_type
    values = np.asarray(values)
    n, shape = len(values), values.shape[1:]
    flat = pa.array(np.ascontiguousarray(values).reshape(-1), type=value_type)
    if nested:
        out = flat
        for size in reversed(shape):
            out = pa.FixedSizeListArray.from_arrays(out, size)
    else:
        out = pa.FixedSizeListArray.from_arrays(flat, int(np.prod(shape)) if shape else 1)
    if valid is not None and not np.all(valid):
        out = pa.FixedSizeListArray.from_arrays(out.values, out.type.list_size, mask=pa.array(~np.asarray(valid)))
    assert len(out) == n
    return out


def to_series(name: str, values: np.ndarray, *, dtype: pl.DataType = pl.Float64, nested: bool = False,
              valid: np.ndarray | None = None) -> pl.Series:
    """An `(N, *shape)` array as a polars Array column: flat (`Array(f64, 16)` for (N, 4, 4)) or, with
    `nested`, one Array level per axis. `valid` (N,) marks the rows that are not null."""
    values = np.asarray(values)
    shape = values.shape[1:]
    inner = shape if nested else (int(np.prod(shape)),)
    series = pl.Series(name, values.reshape((len(values), *inner)), dtype=pl.Array(dtype, inner))
    if valid is not None and not np.all(valid):
        series = pl.select(pl.when(pl.Series(np.asarray(valid, dtype=bool))).then(series)).to_series().alias(name)
    return series
