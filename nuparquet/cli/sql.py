"""`nuparquet sql OUT "SELECT …"`: polars SQL over every dataset of a converted directory.

Also the DataFrame printers the analytics subcommands share (`print_frame`: table, csv or json).
"""

from __future__ import annotations

import datetime as dt
import json
import math
import sys
from typing import TextIO

import polars as pl

from nuparquet.dataset import open_dataset

FORMATS = ("table", "csv", "json")
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


def format_table(df: pl.DataFrame, *, max_rows: int | None = None) -> str:
    """Plain-text table: left-aligned strings, right-aligned numbers, no wrapping."""
    rows = df.head(max_rows) if max_rows is not None else df
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


def register(sub) -> None:
    p = sub.add_parser(
        "sql",
        help="run a polars SQL query over a converted dataset",
        description="Run one SQL query (polars SQL dialect) over the datasets of OUT and print the result. "
        "Tables: frames, annotations, scenes, instances, and every source table as sample, scene, "
        "sample_annotation, … (also \"tables/sample\" — quoted, because of the slash — and tables_sample). "
        "Only the columns and row groups the query needs are read. Exit 1 for bad SQL or unknown "
        "tables or columns (the message says what is wrong).",
        epilog="example: nuparquet sql OUT \"SELECT category_name, COUNT(*) AS n FROM annotations "
        "GROUP BY category_name ORDER BY n DESC\"",
    )
    p.add_argument("out", metavar="OUT", help="a directory written by `nuparquet convert` (or a URL polars can scan)")
    p.add_argument("query", help="the SQL query (quote it for the shell)")
    p.add_argument("--format", choices=FORMATS, default="table",
                   help="table (readable, default), csv (header + rows) or json (a list of row objects)")
    p.add_argument("--max-rows", type=int, default=100, metavar="N",
                   help="rows shown in table format (default 100; csv and json print every row)")
    p.set_defaults(run=run)


def run(args) -> int:
    result = open_dataset(args.out).sql(args.query)
    print_frame(result, args.format, max_rows=args.max_rows if args.format == "table" else None)
    if args.format == "table":
        print(f"({result.height:,} row{'s' if result.height != 1 else ''})")
    return 0
