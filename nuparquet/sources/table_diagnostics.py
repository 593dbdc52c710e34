"""The slow paths of the table reader, run only when pass 1 found a problem: every record whose field has the
wrong JSON type or structure, named with its index and token (values quoted through `problems.echo`)."""

from __future__ import annotations

import duckdb

from nuparquet.problems import Problem, echo
from nuparquet.schemas import Field

_SCALAR_WORDS = {"string": "a string", "bool": "a boolean", "int64": "an integer", "float64": "a number"}


def json_path(name: str) -> str:
    return "'$.\"" + name.replace("'", "''").replace('"', '\\"') + "\"'"


def diagnose_scalar(con: duckdb.DuckDBPyConnection, objects: str, file: str, f: Field, allowed: set,
                     limit: int = 50) -> list[Problem]:
    """Every record whose scalar field `f` has a JSON type outside `allowed` (the slow path, only on error)."""
    kinds = ", ".join(f"'{k}'" for k in allowed if k is not None)
    path = json_path(f.name)
    where = f"kind IS NULL OR kind NOT IN ({kinds})" if None not in allowed else f"kind NOT IN ({kinds})"
    query = f"""
        SELECT idx, token, kind, value FROM (
            SELECT row_number() OVER () - 1 AS idx, json_extract_string(json, '$.token') AS token,
                   json_type(json, {path}) AS kind, json_extract(json, {path})::VARCHAR AS value FROM {objects})
        WHERE {where} ORDER BY idx"""
    rows = con.sql(query).fetchall()
    problems = []
    for idx, token, kind, value in rows[:limit]:
        got = "a missing value or null" if kind in (None, "NULL") else echo(value, quote=False)
        if f.type == "int64" and kind == "DOUBLE":
            got += " (not an integer: it would be truncated)"
        problems.append(Problem(file, f"field {f.name!r} must be {_SCALAR_WORDS[f.type]}, got {got}", idx, token))
    if len(rows) > limit:
        problems.append(Problem(file, f"{len(rows) - limit} more records with a bad {f.name!r}", omitted=len(rows) - limit))
    return problems


def diagnose_unusable_floats(con: duckdb.DuckDBPyConnection, objects: str, file: str, f: Field,
                              limit: int = 50) -> list[Problem]:
    """Records whose integer field `f`, read by DuckDB as a double, cannot be kept: an integer literal beyond the
    64-bit range (Python's json reads it exactly; as a double it would change), and for a required field (a
    timestamp) NaN, an infinity or a value beyond int64."""
    path = json_path(f.name)
    unusable = "isnan(v) OR isinf(v) OR abs(v) >= 9.2e18 OR " if f.required else ""
    rows = con.sql(f"""
        SELECT idx, token, value FROM (
            SELECT row_number() OVER () - 1 AS idx, json_extract_string(json, '$.token') AS token,
                   json_type(json, {path}) AS kind, json_extract(json, {path})::VARCHAR AS value,
                   json_extract(json, {path})::DOUBLE AS v FROM {objects})
        WHERE kind = 'DOUBLE' AND ({unusable}regexp_full_match(value, '-?[0-9]+'))
        ORDER BY idx LIMIT {limit}""").fetchall()
    return [Problem(file, f"field {f.name!r} must be an integer within the 64-bit range, got {echo(value, 40, quote=False)}",
                    idx, token) for idx, token, value in rows]


def diagnose_beyond_int64(con: duckdb.DuckDBPyConnection, objects: str, file: str, f: Field,
                          limit: int = 50) -> list[Problem]:
    """Records whose integer field `f` holds an integer between 2**63 and 2**64 (DuckDB types it UBIGINT; int64
    cannot hold it)."""
    path = json_path(f.name)
    rows = con.sql(f"""
        SELECT idx, token, value FROM (
            SELECT row_number() OVER () - 1 AS idx, json_extract_string(json, '$.token') AS token,
                   json_type(json, {path}) AS kind, json_extract(json, {path})::VARCHAR AS value FROM {objects})
        WHERE kind = 'UBIGINT' AND value::UBIGINT > 9223372036854775807 ORDER BY idx LIMIT {limit}""").fetchall()
    return [Problem(file, f"field {f.name!r} must be an integer within the 64-bit range, got {echo(value, 40, quote=False)}",
                    idx, token) for idx, token, value in rows]


def sql_ident(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def _accepted_structures(f: Field) -> tuple[set[str], str]:
    """JSON structures (duckdb json_structure) a list field may hold, and a word for the error message."""
    if f.type == "list<string>":
        return {'["VARCHAR"]', '["NULL"]'}, "a list of strings"
    if f.nested_in_json:
        return {'[["DOUBLE"]]', '[["UBIGINT"]]', '[["BIGINT"]]', '["NULL"]'}, "a 3x3 list of numbers or []"
    return {'["DOUBLE"]', '["UBIGINT"]', '["BIGINT"]'}, "a list of numbers"


def diagnose_field(con: duckdb.DuckDBPyConnection, src: str, file: str, f: Field, limit: int = 50) -> list[Problem]:
    """Every record whose list field `f` has the wrong JSON structure (the slow path, only on error).
    `src` is an unclosed `read_json(...` call."""
    structures, word = _accepted_structures(f)
    col = sql_ident(f.name)
    allowed = ", ".join("'" + k.replace("'", "''") + "'" for k in structures)
    query = f"""
        SELECT idx, token, value FROM (
            SELECT row_number() OVER () - 1 AS idx, token ->> '$' AS token, json_structure({col}) AS structure,
                   {col}::VARCHAR AS value
            FROM {src}, columns={{token: 'JSON', {col}: 'JSON'}}))
        WHERE structure IS NULL OR structure NOT IN ({allowed})
        ORDER BY idx LIMIT {limit}"""
    return [Problem(file, f"field {f.name!r} must be {word}, got {'a missing value' if value is None else echo(value, quote=False)}",
                    idx, token)
            for idx, token, value in con.sql(query).fetchall()]
