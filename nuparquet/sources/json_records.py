"""JSON records (a list of objects parsed with Python's json) as typed Arrow columns, exactly reversible.

Used for inputs whose fields are not declared in `schemas/` (CAN bus messages, their meta and route files):
each field is typed from its values across every record given — bool, int64, float64, string, fixed-size or
variable lists of numbers or strings — and whatever would not come back identical from Arrow is recorded so
that `export-json` writes each record back equal field for field and in its own key order:
- `int_values`: positions of JSON integers inside a float field (`0` among `0.5`s stays `0`);
- `key_orders`: records whose key order differs from the first record's;
- `json_fields`: fields holding objects (or mixed lists), kept as their JSON text.
A value whose type contradicts the field's (a string among numbers, a missing field) is a `Problem`.
"""

from __future__ import annotations

import itertools
import json
import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from nuparquet.problems import Problem

INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1


@dataclass
class Located:
    """Where each record came from (for problems): record i is `files[file_of[i]]`, index `i - starts[...]`."""

    files: list[str]
    starts: list[int]  # first record index of each file

    def where(self, i: int) -> tuple[str, int]:
        k = max(j for j, s in enumerate(self.starts) if s <= i)
        return self.files[k], i - self.starts[k]


@dataclass
class Columns:
    table: pa.Table
    keys: list[str]  # the first record's key order
    json_fields: list[str] = field(default_factory=list)
    int_values: dict[str, list] = field(default_factory=dict)  # field -> [i] or [[i, j]] (global record indices)
    key_orders: dict[int, list[str]] = field(default_factory=dict)  # global record index -> its key order


def range_facts(columns: Columns, start: int, stop: int) -> dict:
    """What records [start, stop) of `columns` need to come back exactly, renumbered from `start`: their
    `int_values` (integers among floats) and `key_orders` (another key order), each only when not empty. For a file
    typed together with others (one CAN bus message type over many scenes, the layers of one map)."""
    facts: dict = {}
    ints = {}
    for name, positions in columns.int_values.items():
        local = [[p[0] - start, p[1]] if isinstance(p, list) else p - start for p in positions
                 if start <= (p[0] if isinstance(p, list) else p) < stop]
        if local:
            ints[name] = local
    if ints:
        facts["int_values"] = ints
    orders = {str(i - start): keys for i, keys in columns.key_orders.items() if start <= i < stop}
    if orders:
        facts["key_orders"] = orders
    return facts


def _kind(values: list) -> tuple[str, bool]:
    """The field's kind, and whether it holds JSON integers among floats (scalars or list elements)."""
    types = set(map(type, values)) - {type(None)}
    if not types:
        return "null", False
    if types == {bool}:
        return "bool", False
    if types == {int}:
        return "int", False
    if types <= {int, float}:
        return "float", int in types
    if types == {str}:
        return "string", False
    if types == {list}:
        elements = set(map(type, itertools.chain.from_iterable(v for v in values if v is not None)))
        nulls = "_with_nulls" if type(None) in elements else ""  # null elements: Arrow builds those lists
        elements -= {type(None)}
        if not elements or elements == {int}:
            return "list_int" + nulls, False
        if elements <= {int, float}:
            return "list_float" + nulls, int in elements
        if elements == {str}:
            return "list_string", False
        return "json", False
    if types == {dict}:
        return "json", False
    return "mixed", False


def _majority(values: list) -> type:
    counts = Counter(type(v) for v in values if v is not None)
    if counts[int] and counts[float]:  # numbers are one kind
        counts[float] += counts.pop(int)
    return counts.most_common(1)[0][0]


def to_columns(records: list[dict], located: Located, what: str) -> tuple[Columns | None, list[Problem]]:
    """Typed columns of `records` (all objects with the same keys); `what` names a record in messages."""
    problems: list[Problem] = []
    if not records:
        return Columns(pa.table({}), []), problems
    keys = list(records[0])
    key_set = set(keys)
    key_orders = {}
    for i, record in enumerate(records):
        if list(record) != keys:
            if set(record) != key_set:
                file, index = located.where(i)
                missing, extra = sorted(key_set - set(record)), sorted(set(record) - key_set)
                detail = "; ".join(filter(None, [missing and f"lacks {', '.join(missing)}",
                                                 extra and f"has extra {', '.join(extra)}"]))
                problems.append(Problem(file, f"{what} {detail} (the first {what} has {', '.join(keys)})", index))
                if len(problems) > 20:
                    return None, problems
            else:
                key_orders[i] = list(record)
    if problems:
        return None, problems
    arrays, json_fields, int_values = {}, [], {}
    for key in keys:
        values = [r[key] for r in records]
        kind, has_ints = _kind(values)
        if kind == "mixed":
            expected = _majority(values)
            for i, v in enumerate(values):
                if v is not None and not (type(v) is expected or (expected is float and type(v) is int)):
                    file, index = located.where(i)
                    problems.append(Problem(file, f"{what} field {key!r} is a {type(v).__name__} where the others "
                                                  f"hold {expected.__name__} values", index))
                    if len(problems) > 20:
                        break
            continue
        present = values if None not in values else [v for v in values if v is not None]
        if kind == "int" and present and not (INT64_MIN <= min(present) and max(present) <= INT64_MAX):
            i = next(i for i, v in enumerate(values) if v is not None and not INT64_MIN <= v <= INT64_MAX)
            file, index = located.where(i)
            problems.append(Problem(file, f"{what} field {key!r}: integer {values[i]} is outside int64", index))
            continue
        if has_ints:  # integers among floats: refuse those float64 cannot hold, remember where the others are
            flat = values if kind == "float" else itertools.chain.from_iterable(v for v in values if v is not None)
            big = next((v for v in flat if type(v) is int and abs(v) > 2**53), None)
            if big is not None:  # float64 cannot hold it exactly: refuse rather than change it
                problems.append(Problem(located.files[0], f"{what} field {key!r}: integer {big} among floats is "
                                                          "beyond 2**53 and would not convert exactly"))
                continue
        if has_ints and kind == "float":
            int_values[key] = [i for i, v in enumerate(values) if type(v) is int]
        if has_ints and kind.startswith("list_float"):
            ints = [[i, j] for i, v in enumerate(values) if v is not None for j, x in enumerate(v) if type(x) is int]
            if ints:
                int_values[key] = ints
        arrays[key] = _array(values, kind)
        if kind == "json":
            json_fields.append(key)
    if problems:
        return None, problems
    return Columns(pa.table(arrays), keys, json_fields, int_values, key_orders), problems


def _array(values: list, kind: str) -> pa.Array:
    if kind == "json":
        return pa.array([None if v is None else json.dumps(v) for v in values], pa.string())
    scalar = {"bool": pa.bool_(), "int": pa.int64(), "float": pa.float64(), "string": pa.string(), "null": pa.null()}
    if kind in scalar:
        return pa.array(values, scalar[kind])
    numeric = not kind.endswith("_with_nulls") and kind != "list_string"
    kind = kind.removesuffix("_with_nulls")
    element = {"list_int": pa.int64(), "list_float": pa.float64(), "list_string": pa.string()}[kind]
    lengths = set(map(len, values)) if None not in values else {len(v) for v in values if v is not None} | {-1}
    # Strings stay variable lists even when every record has as many: polars cannot reverse (or take every
    # operation on) a fixed-size list of strings, and a map layer's token lists have no fixed size in the format.
    if len(lengths) == 1 and 0 not in lengths and kind != "list_string":
        size = lengths.pop()
        if numeric:  # numbers: numpy reads the nested lists in C, much faster than pa.array
            flat = np.array(values, dtype=np.int64 if kind == "list_int" else np.float64).reshape(-1)
            return pa.FixedSizeListArray.from_arrays(pa.array(flat, element), size)
        return pa.array(values, pa.list_(element, size))
    return pa.array(values, pa.list_(element))


def to_records(rows: list[dict], keys: list[str], json_fields: list[str], int_values: dict[str, list],
               key_orders: dict[int, list[str]], offset: int = 0) -> list[dict]:
    """Records back from Arrow rows (`to_pylist`), undoing what `to_columns` recorded. `offset`: the global index
    of `rows[0]` (a file's records within the columns of several files)."""
    return records_from_columns({k: [row[k] for row in rows] for k in keys}, len(rows), keys, json_fields,
                                int_values, key_orders, offset)


def records_from_columns(columns: dict[str, list], n: int, keys: list[str], json_fields: list[str],
                         int_values: dict[str, list], key_orders: dict, offset: int = 0) -> list[dict]:
    """`to_records` from columns: `columns[k]` the n Python values of field k (changed in place), records in the
    first record's key order `keys` unless `key_orders` gives a record's own."""
    for name in json_fields:
        columns[name] = [None if v is None else json.loads(v) for v in columns[name]]
    for name, positions in int_values.items():
        values = columns[name]
        for p in positions:
            if isinstance(p, list):
                i, j = p[0] - offset, p[1]
                if 0 <= i < n:
                    values[i][j] = _as_int(values[i][j])
            elif 0 <= p - offset < n:
                values[p - offset] = _as_int(values[p - offset])
    out = [dict(zip(keys, values)) for values in zip(*(columns[k] for k in keys))] if keys else [{} for _ in range(n)]
    for i, order in key_orders.items():
        i = int(i) - offset
        if 0 <= i < n and order:
            out[i] = {k: out[i][k] for k in order}
    return out


def _as_int(value: float) -> int:
    return int(value) if math.isfinite(value) else value
