"""Read the JSON tables of a nuScenes-layout dataroot into typed Arrow tables, in one pass per file.

Each file goes once through a compiled scanner (`sources/table_scan.py`, `sources/json_scan.py`) that checks the
JSON as Python's json reads it (the devkit's reader: no trailing commas, no bare `nan`, UTF-8, ...) and writes
every field into typed columns while it records what a typed column cannot hold: each record's key order, integer
vs float literals (also inside lists of numbers), and the raw JSON text of fields the schema does not know (written
back verbatim by export-json). Then, per field and without another pass over the file, this module applies the
schema: JSON types (every record with a wrong one named, with its index and token), integers within int64,
integers written as floats (kept as integers when all are integral, else a float64 column), integers in float
lists that float64 cannot hold exactly (refused), lists of numbers that hold anything but numbers (refused), list
lengths, required fields. The previous reader (DuckDB in two passes plus a strict-JSON scan) parsed every file
three times; see BENCHMARKS.md, row 1.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pyarrow as pa

from nuparquet.errors import UsageError
from nuparquet.problems import Problem
from nuparquet.schemas import Schema, table_schemas

READ_THREADS = 2  # tables scanned at once (the scanner releases the GIL)


@dataclass
class SourceTable:
    """One parsed JSON table: typed Arrow data plus what export-json needs to write it back verbatim."""

    name: str
    path: Path
    table: pa.Table
    key_order: list[str]  # the JSON key order of the source records
    float_fields: list[str] = field(default_factory=list)  # int fields the source stores as JSON floats
    json_fields: list[str] = field(default_factory=list)  # fields the schema does not know: raw JSON text
    layouts: list[list[str]] = field(default_factory=list)  # key lists of records (table_typing), when several
    inferred: dict | None = None  # a table the schemas do not describe: what json_records needs to write it back
    finished: dict = field(default_factory=dict)  # what `read_tables(finish=...)` made of it (the conversion's)


@dataclass
class ReadResult:
    tables: dict[str, SourceTable]
    problems: list[Problem]
    files: dict[str, dict]  # file name -> {"bytes", "mtime"}


def version_dir(dataroot: Path | str, version: str) -> Path:
    if not version or not version.strip() or "/" in version or version in (".", ".."):
        raise UsageError(f"--version must name the version folder inside the dataroot (e.g. v1.0-mini), got {version!r}")
    dataroot = Path(dataroot)
    if not dataroot.is_dir():
        raise UsageError(f"dataroot {dataroot} is not a directory")
    folder = dataroot / version
    if not folder.is_dir():
        # A version folder holds the core tables; can_bus/ (or any other folder of JSON files) is not one.
        core = [schema.source for schema in table_schemas().values() if not schema.optional]
        found = sorted(p.name for p in dataroot.iterdir() if p.is_dir() and any((p / name).is_file() for name in core))
        hint = f"; versions found: {', '.join(found)}" if found else ""
        raise UsageError(f"version folder {folder} does not exist{hint}")
    return folder


def read_tables(
    dataroot: Path | str, version: str, *, on_table: Callable[[str], None] | None = None,
    finish: Callable[[SourceTable], None] | None = None,
) -> ReadResult:
    """Parse every table of `dataroot/version`: the core tables (a missing one is a problem) and the
    optional extensions (lidarseg, panoptic) when present. Problems are collected, not raised. `finish(table)`
    runs on each table read without problems, in the thread that read it (the conversion writes tables/ there,
    while the other thread still reads)."""
    folder = version_dir(dataroot, version)
    tables: dict[str, SourceTable] = {}
    problems: list[Problem] = []
    files: dict[str, dict] = {}
    present = {name: folder / schema.source for name, schema in table_schemas().items()
               if (folder / schema.source).is_file()}
    # Two tables are scanned at once (largest first, so the big three spread over both cores). Results are taken
    # in schema order: the same problems, same order.
    with ThreadPoolExecutor(READ_THREADS) as pool:
        reading = {name: pool.submit(_read_and_finish, path, table_schemas()[name], finish)
                   for name, path in sorted(present.items(), key=lambda item: -item[1].stat().st_size)}
        for name, schema in table_schemas().items():
            if on_table:
                on_table(name)
            if name not in present:
                if not schema.optional:
                    problems.append(Problem(schema.source, f"table {name} is missing (expected {folder / schema.source})"))
                continue
            stat = present[name].stat()
            files[schema.source] = {"bytes": stat.st_size, "mtime": stat.st_mtime}
            table, table_problems = reading[name].result()
            problems += table_problems
            if table is not None:
                tables[name] = table
    known = {s.source for s in table_schemas().values()}
    for path in sorted(p for p in folder.glob("*.json") if p.name not in known):  # T4: object_ann, vehicle_state, ...
        if on_table:
            on_table(path.stem)
        stat = path.stat()
        files[path.name] = {"bytes": stat.st_size, "mtime": stat.st_mtime}
        table, table_problems = read_extra_table(path)
        problems += table_problems
        if table is not None:
            if finish is not None:
                finish(table)
            tables[table.name] = table
    return ReadResult(tables, problems, files)


def _read_and_finish(path: Path, schema: Schema, finish: Callable[[SourceTable], None] | None):
    table, problems = read_table(path, schema)
    if table is not None and finish is not None:
        finish(table)
    return table, problems


def read_extra_table(path: Path) -> tuple[SourceTable | None, list[Problem]]:
    """A table the schemas do not describe (extra tables of derived datasets), typed by inference and exactly
    reversible (`sources.json_records`)."""
    import json

    from nuparquet.sources.json_records import Located, to_columns

    try:
        records = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        return None, [Problem(path.name, f"not valid JSON ({exc})")]
    if not isinstance(records, list) or not all(isinstance(r, dict) for r in records):
        return None, [Problem(path.name, "expected a JSON array of records (an extra table of the version folder)")]
    columns, problems = to_columns(records, Located([path.name], [0]), "record")
    if columns is None:
        return None, problems
    inferred = {"keys": columns.keys, "json_fields": columns.json_fields, "int_values": columns.int_values,
                "key_orders": {str(k): v for k, v in columns.key_orders.items()}}
    return SourceTable(path.stem, path, columns.table, columns.keys, inferred=inferred), []


def _first_chars(path: Path, n: int = 2) -> tuple[str, int]:
    """The first `n` non-whitespace characters of a file (enough to tell an array, an object, `[]`), and the byte
    position just after the first of them."""
    out: list[str] = []
    after, at = 0, 0
    with path.open("rb") as f:
        while len(out) < n and (chunk := f.read(4096)):
            for i, c in enumerate(chunk.decode("utf-8", errors="replace")):
                if len(out) >= n:
                    break
                if c not in " \t\r\n":
                    if not out:
                        after = at + i + 1  # the first character is ASCII when it matters ('[')
                    out.append(c)
            at += len(chunk)
    return "".join(out), after


def read_table(path: Path, schema: Schema) -> tuple[SourceTable | None, list[Problem]]:
    """One table file: (SourceTable, []) or (None, its problems)."""
    from nuparquet.sources.table_scan import scan_table
    from nuparquet.sources.table_typing import typed_table

    file = path.name
    head, after = _first_chars(path)
    if not head.startswith("["):
        what = "is a JSON object" if head.startswith("{") else ("is empty" if not head else f"starts with {head[:1]!r}")
        return None, [Problem(file, f"expected a JSON array of records, but the file {what}")]
    if head == "[]":  # (what follows is checked by the scan: whitespace only)
        scanned, problems = scan_table(path, (), after)
        if scanned is None:
            return None, problems
        empty = pa.table({f.name: pa.array([], f.arrow_type) for f in schema.fields})
        return SourceTable(schema.name, path, empty, schema.names), []
    scanned, problems = scan_table(path, schema.fields, after)
    if scanned is None:
        return None, problems
    typed, problems = typed_table(path, schema, scanned)
    if typed is None:
        return None, problems
    return SourceTable(schema.name, path, typed.table, typed.key_order, typed.float_fields, typed.json_fields,
                       typed.layouts), []
