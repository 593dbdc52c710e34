"""How the CLI prints tables: readable terminal tables, CSV or JSON (shared by info, stats and sql)."""

from __future__ import annotations

import datetime as dt
import json
import math
import sys
from typing import TextIO

import polars as pl

from nuparquet.cli.arguments import FORMATS  # noqa: F401 - the formats these printers take
MAX_CELL = 48  # characters of a string cell in table output


def _cell(value, decimals: int = 3) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value) or math.isinf(value):
            return str(value)
        return f"{value:.{decimals}f}"
    if isinstance(value, dt.datetime):
        return value.strftime("%Y-%m-%d %H:%M:%S") + (" UTC" if value.tzinfo else "")
    text = str(value) if not isinstance(value, (list, tuple, dict)) else json.dumps(value)
    return text if len(text) <= MAX_CELL else text[: MAX_CELL - 1] + "…"


def _decimals(column: pl.Series) -> int:
    """Decimals for a float column: one precision per column, fewer for large values."""
    finite = column.filter(column.is_finite())
    largest = float(finite.abs().max()) if finite.len() else 0.0
    return 3 if largest < 10 else 2 if largest < 10_000 else 1


def _datetimes_as_text(df: pl.DataFrame) -> pl.DataFrame:
    """Datetime columns as ISO 8601 text, formatted by polars: Python's datetime stops at year 9999, and timestamps
    in the wrong unit (nanoseconds read as microseconds) land far beyond it; they must print, not crash."""
    columns = [pl.col(name).dt.to_string("%Y-%m-%dT%H:%M:%S%.6f") for name, dtype in df.schema.items()
               if isinstance(dtype, pl.Datetime)]
    return df.with_columns(columns) if columns else df


def format_table(df: pl.DataFrame, *, max_rows: int | None = None) -> str:
    """Plain-text table: left-aligned strings, right-aligned numbers, no wrapping."""
    rows = _datetimes_as_text(df.head(max_rows) if max_rows is not None else df)
    numeric = [dtype.is_numeric() for dtype in df.dtypes]
    decimals = [_decimals(rows[name]) if dtype.is_float() else 3 for name, dtype in rows.schema.items()]
    cells = [[_cell(v, d) for v, d in zip(row, decimals)] for row in rows.iter_rows()]
    widths = [max([len(name)] + [len(r[i]) for r in cells]) for i, name in enumerate(df.columns)]

    def line(values: list[str]) -> str:
        return "  ".join(v.rjust(w) if num else v.ljust(w) for v, w, num in zip(values, widths, numeric)).rstrip()

    out = [line(df.columns), "  ".join("-" * w for w in widths)] + [line(r) for r in cells]
    if max_rows is not None and df.height > max_rows:
        out.append(f"… {df.height - max_rows:,} more rows")
    return "\n".join(out)


def _flat(df: pl.DataFrame) -> pl.DataFrame:
    """Nested columns (lists, arrays, structs) as JSON text, so that CSV can hold them."""
    nested = [name for name, dtype in df.schema.items() if dtype.is_nested()]
    if not nested:
        return df
    return df.with_columns(
        pl.Series(name, [None if v is None else json.dumps(v) for v in df[name].to_list()], dtype=pl.String)
        for name in nested)


def records(df: pl.DataFrame) -> list[dict]:
    """Rows as JSON-ready dicts (datetimes as ISO 8601 text, NaN as null)."""
    return json.loads(df.write_json())


def print_frame(df: pl.DataFrame, fmt: str, *, title: str | None = None, stream: TextIO | None = None,
                max_rows: int | None = None) -> None:
    """Print `df` as a table (with an optional title line), CSV (header + rows) or JSON (a list of records)."""
    stream = stream or sys.stdout
    if fmt == "table":
        if title:
            stream.write(f"\n{title}\n")
        stream.write(format_table(df, max_rows=max_rows) + "\n")
    elif fmt == "csv":
        stream.write(_flat(df).write_csv())
    elif fmt == "json":
        stream.write(json.dumps(records(df), indent=1) + "\n")
    else:
        raise ValueError(f"unknown format {fmt!r}")
