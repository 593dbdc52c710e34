"""What a typed column cannot hold about each JSON record, kept beside it so `export-json` writes it back exactly.

Real derived datasets are less regular than nuScenes (Lyft Level 5, TIER IV T4): records in another key order,
fields present in some records only (Lyft's lidar rows have no width/height), integers inside float lists
(`"rotation": [1, 0, 0, 0]`), one integer written as a float (`"timestamp": 1535639716773683.0`). The column keeps
the value; two hidden columns of `tables/<name>` keep the rest, only when a table needs them:
- `_layout` (uint16): the record's keys in its own order, as an index into the manifest's `layouts` for the table
  (0 = the table's `key_order`); keys a record lacks are absent from its layout, so they stay absent;
- `_json_types` (list<string>): where the JSON type differs from the column's: `"f"` for a scalar field written
  as an integer in a float column or as a float in an integer column; `"f:iffi"` for a float list whose elements
  marked `i` were written as integers (nested lists flattened row-major).
Both are found with DuckDB in the pass the reader makes anyway, plus one more pass only over tables that need it.
"""

from __future__ import annotations

import duckdb
import pyarrow as pa
import pyarrow.compute as pc

from nuparquet.schemas import Field

LAYOUT, JSON_TYPES = "_layout", "_json_types"
HIDDEN = (LAYOUT, JSON_TYPES)
INTS = "['UBIGINT', 'BIGINT']"


def is_float_list(f: Field) -> bool:
    return f.type.startswith("fixed_size_list") and "float" in f.type


def _path(name: str, nested: bool = False) -> str:
    escaped = name.replace("'", "''").replace('"', '\\"')
    return f"'$.\"{escaped}\"[*]" + ("[*]" if nested else "") + "'"


def element_types(f: Field) -> str:
    """SQL: the JSON types of a float list field's elements (flattened)."""
    return f"list_transform(json_extract(json, {_path(f.name, f.nested_in_json)}), lambda x: json_type(x))"


def has_int_elements(f: Field) -> str:
    """SQL (for pass 1's GROUP BY): does this record hold an integer inside float list `f`?"""
    return f"list_has_any({element_types(f)}, {INTS})"


def all_integral(con: duckdb.DuckDBPyConnection, objects: str, path: str) -> bool:
    """Are all JSON floats of a field integral and exactly representable (so an integer column can hold them)?"""
    rows = con.sql(f"SELECT coalesce(bool_and(v = floor(v) AND abs(v) <= 9007199254740992), true) FROM "
                   f"(SELECT json_extract(json, {path})::DOUBLE AS v FROM {objects} "
                   f"WHERE json_type(json, {path}) = 'DOUBLE')").fetchall()
    return bool(rows[0][0])


def exceptions(con: duckdb.DuckDBPyConnection, objects: str, key_order: list[str], scalar_marks: dict[str, str],
               list_fields: list[Field], need_layouts: bool) -> tuple[dict[str, pa.Array], list[list[str]]]:
    """The hidden columns of one table, in record order, and its layouts (layouts[0] = `key_order`).

    `scalar_marks`: field -> JSON path of scalar fields whose JSON type may differ from the column's; each maps to
    the JSON types that count as different (as a SQL list). `list_fields`: float lists holding integers somewhere.
    """
    marks = [f"CASE WHEN json_type(json, {path}) IN {kinds} THEN '{name}' END" for name, (path, kinds)
             in scalar_marks.items()]
    for f in list_fields:
        types = element_types(f)
        name = f.name.replace("'", "''")
        marks.append(f"CASE WHEN list_has_any({types}, {INTS}) THEN '{name}:' || list_aggregate(list_transform("
                     f"{types}, lambda x: CASE WHEN x IN {INTS} THEN 'i' ELSE 'f' END), 'string_agg', '') END")
    selects = ["json_keys(json) AS keys" if need_layouts else "NULL AS keys"]
    selects.append(f"list_filter([{', '.join(marks)}], lambda x: x IS NOT NULL) AS marks" if marks else "NULL AS marks")
    table = con.sql(f"SELECT {', '.join(selects)} FROM {objects}").to_arrow_table()
    out: dict[str, pa.Array] = {}
    layouts = [list(key_order)]
    if need_layouts:
        joined = pc.binary_join(table.column("keys"), "\x1f").combine_chunks()
        distinct = pc.unique(joined).to_pylist()
        ids = {"\x1f".join(key_order): 0}
        for text in distinct:
            if text not in ids:
                ids[text] = len(layouts)
                layouts.append(text.split("\x1f") if text else [])
        index = pc.index_in(joined, value_set=pa.array(list(ids), pa.string()))
        lookup = pa.array(list(ids.values()), pa.uint16())
        out[LAYOUT] = lookup.take(index)
    if marks:
        column = table.column("marks").combine_chunks()
        empty = pc.equal(pc.list_value_length(column), 0)
        out[JSON_TYPES] = pc.if_else(empty, pa.scalar(None, column.type), column)
    return out, layouts


def restore(record: dict, marks: list[str] | None, int_columns: set[str]) -> None:
    """Give `record` (built from the columns) back the JSON types recorded in `marks`."""
    for mark in marks or ():
        name, _, pattern = mark.partition(":")
        value = record.get(name)
        if value is None:
            continue
        if not pattern:
            record[name] = float(value) if name in int_columns else int(value)
            continue
        nested = bool(value) and isinstance(value[0], list)
        flat = [x for row in value for x in row] if nested else list(value)
        flat = [int(x) if flag == "i" else x for x, flag in zip(flat, pattern)]
        if nested:
            width = len(value[0])
            record[name] = [flat[i:i + width] for i in range(0, len(flat), width)]
        else:
            record[name] = flat
