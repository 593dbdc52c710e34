"""SQL over a converted directory (`Dataset.sql`): the names every dataset is registered under, and the guard
that keeps a query inside the dataset.

Every dataset is registered under its manifest name (``frames``, ``annotations``, ``scenes``, ``instances``,
``"tables/sample"``, ``"map/lane"`` — a name with a slash must be double-quoted in SQL), and each source table also
under two plain aliases: ``sample`` and ``tables_sample``. An alias is skipped if it would shadow a manifest name.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import TYPE_CHECKING

import polars as pl

from nuparquet.errors import FormatError, QueryError

if TYPE_CHECKING:
    from nuparquet.dataset.core import Dataset

QUOTING_HINT = 'a name with a slash is double-quoted: SELECT * FROM "map/lane"; tables also as sample, tables_sample'


def sql_names(datasets: Iterable[str]) -> dict[str, str]:
    """Every SQL name of `datasets` (manifest names), mapped to the dataset it stands for."""
    datasets = list(datasets)
    names = {name: name for name in datasets}
    for name in datasets:
        if name.startswith("tables/"):
            table = name.removeprefix("tables/")
            for alias in (table, f"tables_{table}"):
                names.setdefault(alias, name)
    return names


# polars SQL table functions that read files (polars.SQLContext: read_csv, read_parquet, read_json, read_ipc).
_FILE_FUNCTION = re.compile(r"\b(read_(?:csv|parquet|json|ndjson|ipc|delta|excel|avro))\s*\(", re.IGNORECASE)
_SQL_STRING = re.compile(r"'(?:[^']|'')*'|\"(?:[^\"]|\"\")*\"")


def file_reading_function(query: str) -> str | None:
    """The first file-reading table function called in `query` (string literals and quoted names ignored)."""
    match = _FILE_FUNCTION.search(_SQL_STRING.sub("''", query))
    return match.group(1) if match else None


def run_sql(ds: Dataset, query: str, *, lazy: bool, allow_file_access: bool) -> pl.DataFrame | pl.LazyFrame:
    """`Dataset.sql`: the query over `ds.sql_context()`, file-reading functions refused unless allowed, polars'
    errors as `QueryError` (a damaged Parquet file named as such)."""
    if not allow_file_access:
        function = file_reading_function(query)
        if function is not None:
            raise QueryError(f"SQL reads only this dataset: {function}(...) would read another file (pass "
                             "allow_file_access=True, or --allow-file-access, to allow it)")
    try:
        result = ds.sql_context().execute(query, eager=False)
        return result if lazy else result.collect()
    except pl.exceptions.PolarsError as exc:
        message = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        damaged = ds.damaged_files() if "parquet" in message.lower() and not ds.is_remote else []
        if damaged:
            raise FormatError(f"{damaged[0][0]} is damaged ({damaged[0][1]}); convert the dataset again") from exc
        hint = ""
        lowered = message.lower()
        if "not found" in lowered and ("relation" in lowered or "table" in lowered):
            derived = [n for n in ds.datasets if not n.startswith("tables/")]
            tables = [n.removeprefix("tables/") for n in ds.datasets if n.startswith("tables/")]
            hint = f" (datasets: {', '.join(derived)}; source tables: {', '.join(tables)}; {QUOTING_HINT})"
        raise QueryError(f"SQL failed: {message}{hint}") from exc
