"""SQL over a converted directory (`Dataset.sql`): the names every dataset is registered under, and the guard
that keeps a query inside the dataset.

Every dataset is registered under its manifest name (``frames``, ``annotations``, ``scenes``, ``instances``,
``"tables/sample"``, ``"map/lane"`` — a name with a slash must be double-quoted in SQL), and each source table also
under two plain aliases: ``sample`` and ``tables_sample``. An alias is skipped if it would shadow a manifest name.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

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
