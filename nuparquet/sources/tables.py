"""Read the JSON tables of a nuScenes-layout dataroot into typed Arrow tables.

Parser choice: DuckDB's `read_json`. nuScenes tables are single JSON arrays of up to ~1 GB (trainval
sample_data: 2.63M records). Measured on a 2-core machine for a 560 MB sample_annotation-shaped file:
DuckDB 2.1 s / 0.55 GB RSS, orjson (GC off) 3.6 s / 3.8 GB, json.load 7-11 s / 2.4 GB, polars.read_json
9.1 s / 4.0 GB. Only DuckDB parses straight into columns without building a Python object per field, so
it is the only one that keeps a whole trainval conversion inside 4 GB.

DuckDB coerces silently when told a type (1.5 read as BIGINT gives 2, 1 read as VARCHAR gives "1"), and
its own type detection over every record (`sample_size=-1`) costs a slow extra parse. So each file is
read in two passes:
1. the layouts of all records, grouped: their keys (`json_keys`: fields the schema does not know, in
   whatever record they first appear, and the source key order) and the JSON type of every scalar field
   (`json_type` with a list of paths). A field with a wrong type sends only that field down a
   diagnostic query naming every offending record; an int field with JSON floats is read as float64.
2. a plain typed read with explicit column types, now known to convert losslessly.
Fields the schema does not know are kept as their raw JSON text and written back verbatim by export-json.

Longer than our ~300-line norm on purpose: the two passes and the checks between them share one file's
state; what could be split off already has its module (`table_layouts`, `table_types`, `table_diagnostics`).
"""

from __future__ import annotations

import os
import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import duckdb
import pyarrow as pa

from nuparquet.errors import UsageError
from nuparquet.problems import Problem, echo
from nuparquet.schemas import Field, Schema, table_schemas
from nuparquet.sources import table_layouts as layouts_
from nuparquet.sources.strict_json import strict_problem
from nuparquet.sources.table_diagnostics import (
    diagnose_beyond_int64, diagnose_field, diagnose_scalar, diagnose_unusable_floats, json_path, sql_ident,
)
from nuparquet.sources.table_types import to_schema_types

READ_THREADS = 2  # tables parsed at once (each also runs its strict-JSON scan on a thread of its own)


@dataclass
class SourceTable:
    """One parsed JSON table: typed Arrow data plus what export-json needs to write it back verbatim."""

    name: str
    path: Path
    table: pa.Table
    key_order: list[str]  # the JSON key order of the source records
    float_fields: list[str] = field(default_factory=list)  # int fields the source stores as JSON floats
    json_fields: list[str] = field(default_factory=list)  # fields the schema does not know: raw JSON text
    layouts: list[list[str]] = field(default_factory=list)  # key lists of records (table_layouts), when several
    inferred: dict | None = None  # a table the schemas do not describe: what json_records needs to write it back


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
    dataroot: Path | str, version: str, *, on_table: Callable[[str], None] | None = None
) -> ReadResult:
    """Parse every table of `dataroot/version`: the core tables (a missing one is a problem) and the
    optional extensions (lidarseg, panoptic) when present. Problems are collected, not raised."""
    folder = version_dir(dataroot, version)
    con = duckdb.connect(config={"threads": os.cpu_count() or 2, "preserve_insertion_order": True})
    tables: dict[str, SourceTable] = {}
    problems: list[Problem] = []
    files: dict[str, dict] = {}
    present = {name: folder / schema.source for name, schema in table_schemas().items()
               if (folder / schema.source).is_file()}
    # DuckDB parses one JSON array on one core: two tables are read at once (largest first, so the big three
    # spread over both), each on its own cursor. Results are taken in schema order: the same problems, same order.
    with ThreadPoolExecutor(READ_THREADS) as pool:
        reading = {name: pool.submit(_read_one_on, con, path, table_schemas()[name])
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
    con.close()
    known = {s.source for s in table_schemas().values()}
    for path in sorted(p for p in folder.glob("*.json") if p.name not in known):  # T4: object_ann, vehicle_state, ...
        if on_table:
            on_table(path.stem)
        stat = path.stat()
        files[path.name] = {"bytes": stat.st_size, "mtime": stat.st_mtime}
        table, table_problems = read_extra_table(path)
        problems += table_problems
        if table is not None:
            tables[table.name] = table
    return ReadResult(tables, problems, files)


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


def _first_chars(path: Path, n: int = 2) -> str:
    """The first `n` non-whitespace characters of a file (enough to tell an array, an object, `[]`)."""
    out: list[str] = []
    with path.open("rb") as f:
        while len(out) < n and (chunk := f.read(4096)):
            out += [c for c in chunk.decode("utf-8", errors="replace") if not c.isspace()][: n - len(out)]
    return "".join(out)


def _sql_path(path: Path) -> str:
    return "'" + str(path).replace("'", "''") + "'"


def _read_one_on(con: duckdb.DuckDBPyConnection, path: Path, schema: Schema) -> tuple[SourceTable | None, list[Problem]]:
    """`_read_one` on a cursor of its own (a DuckDB connection serves one thread at a time)."""
    with con.cursor() as cursor:
        return _read_one(cursor, path, schema)


def _read_one(con: duckdb.DuckDBPyConnection, path: Path, schema: Schema) -> tuple[SourceTable | None, list[Problem]]:
    file = path.name
    head = _first_chars(path)
    if not head.startswith("["):
        what = "is a JSON object" if head.startswith("{") else ("is empty" if not head else f"starts with {head[:1]!r}")
        return None, [Problem(file, f"expected a JSON array of records, but the file {what}")]
    if head == "[]":
        empty = pa.table({f.name: pa.array([], f.arrow_type) for f in schema.fields})
        return SourceTable(schema.name, path, empty, schema.names), []
    # DuckDB would read a trailing comma or a bare `nan` without a word: the strict scan runs on a second thread while
    # DuckDB (which releases the GIL) parses the file in pass 1, and its verdict comes first.
    with ThreadPoolExecutor(1) as pool:
        strict = pool.submit(strict_problem, path)
        table, problems = _read_checked(con, path, schema)
        invalid = strict.result()
    return (None, [invalid]) if invalid is not None else (table, problems)


def _read_checked(con: duckdb.DuckDBPyConnection, path: Path, schema: Schema) -> tuple[SourceTable | None, list[Problem]]:
    file = path.name
    objects = f"read_json_objects({_sql_path(path)}, format='array', maximum_object_size=1073741824)"
    scalars = [f for f in schema.fields if f.type in _SCALAR_KINDS]
    paths = "[" + ", ".join(json_path(f.name) for f in scalars) + "]"
    float_lists = [f for f in schema.fields if layouts_.is_float_list(f)]
    ints_in_lists = "[" + ", ".join(layouts_.has_int_elements(f) for f in float_lists) + "]" if float_lists else "[]"
    try:  # pass 1: the layouts of all records: their keys, the JSON type of every scalar field, integers in float lists
        layouts = con.sql(f"SELECT json_type(json) AS kind, json_keys(json) AS keys, json_type(json, {paths}) AS types, "
                          f"{ints_in_lists} AS list_ints, count(*) AS n FROM {objects} GROUP BY ALL ORDER BY n DESC").fetchall()
    except duckdb.Error as exc:
        return None, [_duckdb_problem(con, objects, file, exc)]
    list_ints = [f for i, f in enumerate(float_lists) if any(row[3] and row[3][i] for row in layouts)]
    layouts = [row[:3] + row[4:] for row in layouts]
    if any(kind != "OBJECT" for kind, *_ in layouts):
        rows = con.sql(f"SELECT idx, kind FROM (SELECT row_number() OVER () - 1 AS idx, json_type(json) AS kind "
                       f"FROM {objects}) WHERE kind != 'OBJECT' ORDER BY idx LIMIT 50").fetchall()
        return None, [Problem(file, f"record is a JSON {kind.lower()}, not an object", idx) for idx, kind in rows]
    key_order = list(layouts[0][1])  # the most common record layout
    for _, keys, _, _ in layouts[1:]:
        key_order += [k for k in keys if k not in key_order]

    clashes = _case_clashes(key_order)
    if clashes:  # DuckDB's columns (and many Parquet readers') ignore case: `Token` and `token` cannot both be kept
        return None, _diagnose_case_clash(con, objects, file, clashes)
    known = {f.name for f in schema.fields}
    extras = [k for k in key_order if k not in known]
    present = set(key_order)
    problems = [Problem(file, f"required field {f.name!r} is missing from every record")
                for f in schema.fields if f.required and f.name not in present]
    seen = {f.name: {types[i] for _, _, types, _ in layouts} for i, f in enumerate(scalars)}
    # An integer field with JSON floats stays integer when every float is integral (each keeps its float form through
    # `_json_types`); one fraction or NaN makes the whole column float64 (its integers marked the same way).
    floats_seen = [f for f in scalars if f.json_float_ok and "DOUBLE" in seen[f.name]]
    float_fields = [f.name for f in floats_seen if not layouts_.all_integral(con, objects, json_path(f.name))]
    for f in floats_seen:  # an integer may be written as a float, but must be a usable one (and not a huge integer)
        problems += diagnose_unusable_floats(con, objects, file, f)
    wrong_kinds = []
    for f in scalars:
        allowed = set(_allowed_kinds(f))
        if f.name in present and not seen[f.name] <= allowed:
            wrong_kinds += diagnose_scalar(con, objects, file, f, allowed)

    def beyond_int64() -> list[Problem]:
        # json_type says UBIGINT for every non-negative integer, so this search reads the whole file once per field:
        # it runs only on a path that already failed (pass 2 refuses a value beyond int64 with a bare cast error).
        return [p for f in scalars if f.type == "int64" and "UBIGINT" in seen[f.name]
                for p in diagnose_beyond_int64(con, objects, file, f)]

    if problems or wrong_kinds:
        return None, problems + beyond_int64() + wrong_kinds

    # pass 2: a plain typed read; pass 1 proved every value has a type that converts losslessly.
    fields = [f for f in schema.fields if f.name in present]
    columns = {f.name: "DOUBLE" if f.name in float_fields else _duckdb_type(f) for f in fields}
    columns |= dict.fromkeys(extras, "JSON")
    spec = "{" + ", ".join(f"{sql_ident(k)}: '{v}'" for k, v in columns.items()) + "}"
    src = f"read_json({_sql_path(path)}, format='array', records=true, maximum_object_size=1073741824"
    try:
        raw = con.sql(f"SELECT * FROM {src}, columns={spec})").to_arrow_table()
    except duckdb.Error as exc:  # an integer beyond int64, or a list field of the wrong shape: name the records
        problems = beyond_int64()
        try:
            problems += [p for f in fields if f.type.startswith(("list", "fixed_size_list"))
                         for p in diagnose_field(con, src, file, f)]
        except duckdb.Error:  # the diagnosis reads the same way and fails the same way (a duplicate key)
            pass
        return None, problems or [_duckdb_problem(con, objects, file, exc)]
    table, problems = to_schema_types(raw, schema, file, float_fields)
    if problems:
        return None, problems
    marks = {}
    for f in scalars:
        kinds = seen.get(f.name, set())
        if f.type == "float64" or f.name in float_fields:
            if kinds & {"UBIGINT", "BIGINT"} and kinds & {"DOUBLE"}:
                marks[f.name] = (json_path(f.name), layouts_.INTS.replace("[", "(").replace("]", ")"))
        elif f.name in {g.name for g in floats_seen}:
            marks[f.name] = (json_path(f.name), "('DOUBLE')")
    several = len({tuple(keys) for _, keys, *_ in layouts}) > 1 or list(layouts[0][1]) != key_order
    record_layouts = [key_order]
    if marks or list_ints or several:
        hidden, record_layouts = layouts_.exceptions(con, objects, key_order, marks, list_ints, several)
        for name, column in hidden.items():
            table = table.append_column(name, column)
    return SourceTable(schema.name, path, table, key_order, float_fields, extras,
                       record_layouts if len(record_layouts) > 1 else []), []


def _case_clashes(keys: list[str]) -> list[tuple[str, str]]:
    """Pairs of keys that differ only in case, in key order."""
    first: dict[str, str] = {}
    pairs = []
    for key in keys:
        if key.lower() in first:
            pairs.append((first[key.lower()], key))
        else:
            first[key.lower()] = key
    return pairs


def _diagnose_case_clash(con: duckdb.DuckDBPyConnection, objects: str, file: str,
                         clashes: list[tuple[str, str]]) -> list[Problem]:
    """The first record holding each pair of keys that differ only in case."""
    problems = []
    for a, b in clashes:
        rows = con.sql(f"""SELECT idx, token FROM (SELECT row_number() OVER () - 1 AS idx, json_keys(json) AS keys,
                               json_extract_string(json, '$.token') AS token FROM {objects})
                           WHERE list_contains(keys, ?) AND list_contains(keys, ?) ORDER BY idx LIMIT 1""",
                       params=[a, b]).fetchall()
        idx, token = rows[0] if rows else (None, None)
        problems.append(Problem(file, f"fields {echo(a)} and {echo(b)} differ only in case; Parquet columns as DuckDB "
                                      "and Spark read them cannot hold both (rename one)", idx, token))
    return problems


_SCALAR_KINDS = {"string": ("VARCHAR",), "bool": ("BOOLEAN",), "int64": ("UBIGINT", "BIGINT"),
                 "float64": ("UBIGINT", "BIGINT", "DOUBLE")}


def _allowed_kinds(f: Field) -> tuple[str | None, ...]:
    """JSON types (duckdb json_type; None for an absent key) field `f` may hold."""
    kinds: tuple[str | None, ...] = _SCALAR_KINDS[f.type] + (("DOUBLE",) if f.json_float_ok else ())
    return kinds if f.required else kinds + ("NULL", None)


_RECORD = re.compile(r'JSON transform error in file ".*?", in record/value (\d+): (?:Object .*?\.\.\. )?(.*)')


def _duckdb_problem(con: duckdb.DuckDBPyConnection, objects: str, file: str, exc: duckdb.Error) -> Problem:
    """DuckDB's error as a problem; one naming a record ("in record/value 5001": DuckDB counts from 1) gets the
    0-based index and the token every other message uses."""
    message = _duckdb_message(exc)
    found = _RECORD.search(message)
    if found is None:
        return Problem(file, message)
    index = int(found.group(1)) - 1
    try:
        token = con.sql(f"SELECT json_extract_string(json, '$.token') FROM (SELECT row_number() OVER () - 1 AS idx, "
                        f"json FROM {objects}) WHERE idx = {index}").fetchall()
    except duckdb.Error:
        token = []
    token = token[0][0] if token and token[0][0] else None
    return Problem(file, f"record {found.group(2)}", index, None if token is None else echo(token, quote=False))


def _duckdb_message(exc: duckdb.Error) -> str:
    text = str(exc).split("\n")[0]
    return text.replace("Invalid Input Error: ", "").replace("Binder Error: ", "")


def _duckdb_type(f: Field) -> str:
    """The DuckDB type a field is read as (lists of numbers as variable lists: lengths are checked after)."""
    if f.type.startswith("fixed_size_list"):
        return "DOUBLE[][]" if f.nested_in_json else "DOUBLE[]"
    return {"string": "VARCHAR", "bool": "BOOLEAN", "int64": "BIGINT", "float64": "DOUBLE",
            "list<string>": "VARCHAR[]"}[f.type]


