"""A scanned table (`sources/table_scan.py`) typed by its schema: every value checked against its field, every record
that does not fit named (index, token, the value quoted), and the hidden columns of `sources/table_layouts.py`
(key orders, JSON literal kinds) added where a table needs them. No pass over the file: numpy over the kinds the
scanner recorded; a record's text is read again only to quote it in a problem.

Longer than our ~300-line norm on purpose: one check per kind of field (strings, integers, lists), each with the
problems it names, read together against the schema's field types; splitting them would split one rule table.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from nuparquet.problems import Problem, echo
from nuparquet.schemas import Field, Schema
from nuparquet.sources import json_scan as k
from nuparquet.sources import table_layouts as layouts_
from nuparquet.sources import table_scan
from nuparquet.sources.table_scan import Column, Scanned

@dataclass
class Typed:
    """A table typed by its schema, and what export-json needs beside it (see `tables.SourceTable`)."""

    table: pa.Table
    key_order: list[str]
    float_fields: list[str]
    json_fields: list[str]
    layouts: list[list[str]]


LIMIT = 50  # records named per field and check
EXACT = 2**53  # integers up to this size are exact in float64
_KIND_WORDS = {k.NULL: "null", k.FALSE: "boolean", k.TRUE: "boolean", k.INT: "number", k.BIGINT: "number",
               k.FLOAT: "number", k.STRING: "string", k.ARRAY: "array", k.OBJECT: "object"}
_SCALAR_WORDS = {"string": "a string", "bool": "a boolean", "int64": "an integer", "float64": "a number"}
_INT64_WORDS = "an integer within the 64-bit range"


class _Report:
    """Problems of one file, each naming the record's index and token and quoting the value."""

    def __init__(self, path: Path, scanned: Scanned):
        self.path, self.scanned = path, scanned
        self.problems: list[Problem] = []
        tokens = scanned.columns.get("token")
        self.tokens = pa.chunked_array(tokens.values, pa.string()) if tokens is not None and tokens.field else None

    def token(self, index: int) -> str | None:
        return None if self.tokens is None else self.tokens[index].as_py()

    def value_text(self, index: int, name: str) -> str:
        """The JSON text of record `index`'s field `name` (read again from the file)."""
        starts = self.scanned.starts
        with self.path.open("rb") as f:
            f.seek(int(starts[index]))
            size = int(starts[index + 1] - starts[index]) if index + 1 < len(starts) else -1
            text = f.read(size).decode("utf-8", errors="replace")
        record, _ = json.JSONDecoder().raw_decode(text)
        return json.dumps(record.get(name))

    def records(self, mask: np.ndarray, message) -> None:
        """A problem for each record where `mask` holds (the first LIMIT, then a count); `message(index)`."""
        indices = np.flatnonzero(mask)
        for i in indices[:LIMIT].tolist():
            self.problems.append(Problem(self.path.name, message(i), i, self.token(i)))

    def wrong(self, f: Field, kind: np.ndarray, bad: np.ndarray, word: str, *, suffix=None) -> None:
        """Records whose field `f` has a JSON value of the wrong type or shape: named with the value."""
        indices = np.flatnonzero(bad)
        for i in indices[:LIMIT].tolist():
            got = ("a missing value or null" if kind[i] in (k.NULL, k.ABSENT)
                   else echo(self.value_text(i, f.name), quote=False) + (suffix(i) if suffix else ""))
            self.problems.append(Problem(self.path.name, f"field {f.name!r} must be {word}, got {got}", i, self.token(i)))
        if len(indices) > LIMIT:
            self.problems.append(Problem(self.path.name, f"{len(indices) - LIMIT} more records with a bad {f.name!r}",
                                         omitted=len(indices) - LIMIT))


def typed_table(path: Path, schema: Schema, scanned: Scanned) -> tuple[Typed | None, list[Problem]]:
    """(Typed, []) or (None, problems)."""
    file = path.name
    report = _Report(path, scanned)
    n = len(scanned.starts)
    not_objects = np.flatnonzero(scanned.layout_of < 0)
    if len(not_objects):
        return None, [Problem(file, f"record is a JSON {_KIND_WORDS[-1 - scanned.layout_of[i]]}, not an object", i)
                      for i in not_objects[:LIMIT].tolist()]
    names = list(scanned.columns)
    if scanned.duplicates.any():
        report.records(scanned.duplicates > 0,
                       lambda i: f'record has duplicate key "{names[scanned.duplicates[i] - 1]}"')
        return None, report.problems
    key_order, layouts, layout_ids = _key_order(scanned)
    clashes = _case_clashes(key_order)
    if clashes:  # Parquet columns as DuckDB and Spark read them ignore case: `Token` and `token` cannot both be kept
        for a, b in clashes:
            ia, ib = names.index(a), names.index(b)
            both = (scanned.kinds[:, ia] != k.ABSENT) & (scanned.kinds[:, ib] != k.ABSENT)
            first = int(np.argmax(both)) if both.any() else None
            report.problems.append(Problem(file, f"fields {echo(a)} and {echo(b)} differ only in case; Parquet columns "
                                                 "as DuckDB and Spark read them cannot hold both (rename one)",
                                           first, None if first is None else report.token(first)))
        return None, report.problems
    present = set(key_order)
    missing = [Problem(file, f"required field {f.name!r} is missing from every record")
               for f in schema.fields if f.required and f.name not in present]
    if missing:
        return None, missing
    columns: dict[str, pa.ChunkedArray] = {}
    float_fields: list[str] = []
    marks: list[pa.Array] = []  # per marked field: its mark per record (null: none)
    for j, (name, column) in enumerate(scanned.columns.items()):
        kind = scanned.kinds[:, j]
        f = column.field
        too_long = kind == k.TOO_LONG
        if too_long.any():
            report.records(too_long, lambda i, name=name: f"field {name!r} holds a string longer than "
                                                          f"{table_scan.MAX_STRING_BYTES:,} bytes (the longest a table "
                                                          "may hold)")
            continue
        if f is None:
            columns[name] = pa.chunked_array(column.values, pa.string())
        elif name not in present:
            columns[name] = pa.chunked_array([pa.nulls(n, f.arrow_type)])
        elif column.cls in (k.C_STRING, k.C_BOOL):
            allowed = [k.STRING if column.cls == k.C_STRING else k.TRUE, k.FALSE if column.cls == k.C_BOOL else k.STRING]
            ok = np.isin(kind, allowed + ([] if f.required else [k.NULL, k.ABSENT]))
            report.wrong(f, kind, ~ok, _SCALAR_WORDS[f.type])
            columns[name] = pa.chunked_array(column.values, f.arrow_type)
            if f.max_bytes is not None and column.cls == k.C_STRING:
                _too_long(report, f, columns[name], columns[name])
        elif column.cls == k.C_INT:
            typed, mark, is_float = _integers(report, f, column, kind)
            if typed is not None:
                columns[name] = typed
            if is_float:
                float_fields.append(name)
            if mark is not None:
                marks.append(mark)
        else:
            typed, mark = _lists(report, f, column, kind)
            if typed is not None:
                columns[name] = typed
            if mark is not None:
                marks.append(mark)
    if report.problems:
        return None, report.problems
    extras = [name for name in key_order if scanned.columns[name].field is None]
    order = schema.names + extras
    nullable = {f.name: f.nullable for f in schema.fields}
    arrays = [columns[name] for name in order]
    fields = [pa.field(name, columns[name].type, nullable=nullable.get(name, True)) for name in order]
    several = len(layouts) > 1
    if several:
        arrays.append(pa.chunked_array([pa.array(layout_ids, pa.uint16())]))
        fields.append(pa.field(layouts_.LAYOUT, pa.uint16()))
    if marks:
        arrays.append(pa.chunked_array([_mark_lists(marks, n)]))
        fields.append(pa.field(layouts_.JSON_TYPES, pa.list_(pa.field("l", pa.string()))))
    table = pa.Table.from_arrays(arrays, schema=pa.schema(fields))
    return Typed(table, key_order, float_fields, extras, layouts if several else []), []


def _key_order(scanned: Scanned) -> tuple[list[str], list[list[str]], np.ndarray]:
    """The table's key order (the most common record layout, then keys other layouts add, in order of their
    frequency), the layouts `_layout` indexes (0 = the key order) and each record's index into them."""
    by_count = sorted(range(len(scanned.layouts)), key=lambda i: -scanned.layout_counts[i])  # stable: first seen first
    key_order = list(scanned.layouts[by_count[0]]) if by_count else []
    for i in by_count[1:]:
        key_order += [name for name in scanned.layouts[i] if name not in key_order]
    layouts = [key_order]
    ids = np.zeros(len(scanned.layouts), np.int64)
    for i, keys in enumerate(scanned.layouts):  # in order of first appearance
        if keys == key_order:
            ids[i] = 0
        else:
            ids[i] = len(layouts)
            layouts.append(list(keys))
    return key_order, layouts, ids[scanned.layout_of] if len(scanned.layout_of) else ids[:0]


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


def _literals(column: Column, mask: np.ndarray) -> tuple[pa.Array, np.ndarray]:
    """The texts of the records where `mask` holds, and their float64 values."""
    texts = pa.chunked_array(column.texts, pa.string()).combine_chunks().filter(pa.array(mask))
    return texts, pc.cast(texts, pa.float64()).to_numpy(zero_copy_only=False)


def _integers(report: _Report, f: Field, column: Column, kind: np.ndarray):
    """An int64 field: (column, marks or None, whether it became float64). Refused: integers beyond int64, floats
    where the field takes none, NaN/infinite/huge floats in a required field, integers float64 would change."""
    name = f.name
    values = pa.chunked_array(column.values, pa.int64())
    allowed = [k.INT, k.BIGINT] + ([k.FLOAT] if f.json_float_ok else []) + ([] if f.required else [k.NULL, k.ABSENT])
    before = len(report.problems)
    report.wrong(f, kind, ~np.isin(kind, allowed), _SCALAR_WORDS["int64"],
                 suffix=lambda i: " (not an integer: it would be truncated)" if kind[i] == k.FLOAT else "")
    report.wrong(f, kind, kind == k.BIGINT, _INT64_WORDS)
    floats = kind == k.FLOAT
    if not floats.any() or len(report.problems) > before:
        return (values if len(report.problems) == before else None), None, False
    texts, numbers = _literals(column, floats)
    if f.required:  # a timestamp: NaN, infinities and values beyond int64 cannot be used
        unusable = np.zeros(len(kind), bool)
        unusable[floats] = ~np.isfinite(numbers) | (np.abs(numbers) >= 9.2e18)
        report.wrong(f, kind, unusable, _INT64_WORDS)
        if len(report.problems) > before:
            return None, None, False
    ints = kind == k.INT
    ints_values = values.fill_null(0).to_numpy()
    if np.all((numbers == np.floor(numbers)) & (np.abs(numbers) <= EXACT)):  # integral floats: an integer column
        merged = ints_values.copy()
        merged[floats] = numbers.astype(np.int64)
        typed = pa.array(merged, pa.int64(), mask=~(ints | floats))
        mark = pa.array(np.where(floats, name, None), pa.string())  # these were floats
        return pa.chunked_array([typed]), mark, False
    # one fraction or NaN: a float64 column; its integers must be exact in float64
    big = ints & ((ints_values > EXACT) | (ints_values < -EXACT))
    inexact = np.zeros(len(kind), bool)
    for i in np.flatnonzero(big).tolist():
        inexact[i] = float(int(ints_values[i])) != int(ints_values[i])
    report.records(inexact, lambda i: f"field {name!r} holds the integer {ints_values[i]} among floats: float64 "
                                      "cannot hold it exactly")
    if len(report.problems) > before:
        return None, None, True
    merged = ints_values.astype(np.float64)
    merged[floats] = numbers
    typed = pa.array(merged, pa.float64(), mask=~(ints | floats))
    mark = pa.array(np.where(ints, name, None), pa.string()) if ints.any() else None
    return pa.chunked_array([typed]), mark, True


def _lists(report: _Report, f: Field, column: Column, kind: np.ndarray):
    """A list field: (column, marks or None). Refused: anything but a list of the field's elements (a string
    inside a list of numbers too), a wrong length, null in a required field, integers float64 would change."""
    name = f.name
    before = len(report.problems)
    strings = column.cls == k.C_STRINGS
    matrix = column.cls == k.C_MATRIX
    word = "a list of strings" if strings else ("a 3x3 list of numbers or []" if matrix else "a list of numbers")
    null = np.isin(kind, [k.NULL, k.ABSENT])
    report.records(null if f.required else np.zeros_like(null), lambda i: f"required field {name!r} is missing or null")
    report.wrong(f, kind, ~null & ~np.isin(kind, [k.LIST_OK, k.LIST_SHAPE]), word)
    lists = pa.chunked_array(column.values, pa.list_(pa.string() if strings else pa.float64()))
    target = f.arrow_type
    lengths = pc.list_value_length(lists).fill_null(-1).to_numpy()
    if not strings:
        size = 9 if matrix else target.list_size
        shape = "3x3" if matrix else size
        empty_ok = f.empty_list_is_null
        wrong_size = (kind == k.LIST_SHAPE) | ((kind == k.LIST_OK) & (lengths != size) & ~((lengths == 0) & empty_ok))
        report.records(wrong_size, lambda i: f"field {name!r} must have {shape} numbers" + (" or be []" if empty_ok else ""))
    if len(report.problems) > before:
        return None, None
    if strings:
        if f.max_bytes is not None:
            _too_long(report, f, pc.list_flatten(lists), lists)
        return (lists.cast(target) if len(report.problems) == before else None), None
    flags = np.concatenate(column.flags) if column.flags else np.zeros(0, np.uint8)
    values = pc.list_flatten(lists).to_numpy(zero_copy_only=False) if len(flags) else np.zeros(0)
    if flags.any():  # integers written as integers: exact in float64, or refused
        _exact_list_integers(report, f, column, flags, values, lists)
        if len(report.problems) > before:
            return None, None
    typed = _fixed(lists, values, target, f.empty_list_is_null, lengths)
    mark = _list_marks(name, flags, lists, len(kind)) if flags.any() else None
    return typed, mark


def _too_long(report: _Report, f: Field, strings, owners) -> None:
    """Records holding a string of field `f` longer than its `max_bytes` (`strings`: the values, or a list field's
    elements with `owners` its lists)."""
    lengths = pc.binary_length(strings).fill_null(0).to_numpy()
    over = lengths > f.max_bytes
    if not over.any():
        return
    if strings is not owners:  # list elements: their records
        parents = pc.list_parent_indices(owners).to_numpy()
        mask = np.zeros(len(owners), bool)
        mask[parents[over]] = True
        longest = {int(parents[i]): int(lengths[i]) for i in np.flatnonzero(over)[::-1]}
    else:
        mask, longest = over, None
    def quoted(i: int) -> str:
        return echo(report.value_text(i, f.name), quote=False) if longest else echo(strings[i].as_py())

    report.records(mask, lambda i: f"field {f.name!r} holds a string of "
                                   f"{(longest[i] if longest else int(lengths[i])):,} bytes, over its limit of "
                                   f"{f.max_bytes:,}: {quoted(i)}")


def _exact_list_integers(report: _Report, f: Field, column: Column, flags: np.ndarray, values: np.ndarray,
                         lists: pa.ChunkedArray) -> None:
    """Integer elements beyond 2**53 whose float64 differs from the integer written: refused, naming the record."""
    suspect = (flags == 1) & (np.abs(values) >= EXACT)
    if not suspect.any():
        return
    owners = pc.list_parent_indices(lists).to_numpy() if len(values) else np.zeros(0, np.int64)
    bad = np.zeros(len(lists), bool)
    for element in np.flatnonzero(suspect)[: 10 * LIMIT].tolist():
        record = int(owners[element])
        literals = json.loads(report.value_text(record, f.name))
        flat = [x for row in literals for x in row] if literals and isinstance(literals[0], list) else literals
        bad[record] |= any(type(x) is int and not _exact_in_float64(x) for x in flat)
    report.records(bad, lambda i: f"field {f.name!r} holds an integer that float64 cannot hold exactly: "
                                  f"{echo(report.value_text(i, f.name), quote=False)}")


def _exact_in_float64(n: int) -> bool:
    try:
        return float(n) == n
    except OverflowError:  # beyond float64's range
        return False


def _fixed(lists: pa.ChunkedArray, values: np.ndarray, target: pa.DataType, empty_is_null: bool,
           lengths: np.ndarray) -> pa.ChunkedArray:
    """Checked variable lists as the schema's fixed-size lists ([] as null where the schema says so)."""
    n = target.list_size
    inner = target.value_type
    flat = pa.array(values, pa.float64())
    if pa.types.is_fixed_size_list(inner):
        flat = pa.FixedSizeListArray.from_arrays(flat, inner.list_size)
    if not empty_is_null or not (lengths == 0).any():
        return pa.chunked_array([pa.FixedSizeListArray.from_arrays(flat, n)])
    keep = lengths != 0
    dense = pa.FixedSizeListArray.from_arrays(flat, n)
    positions = np.maximum(np.cumsum(keep) - 1, 0)
    taken = dense.take(pa.array(positions)) if len(dense) else pa.nulls(len(lengths), target)
    return pa.chunked_array([pc.if_else(pa.array(keep), taken, pa.scalar(None, target))])


def _list_marks(name: str, flags: np.ndarray, lists: pa.ChunkedArray, n: int) -> pa.Array:
    """Per record, `name:iffi` (i: an integer literal) where its list holds an integer, else null."""
    offsets = np.concatenate([[0], np.cumsum(pc.list_value_length(lists).fill_null(0).to_numpy())])
    starts = np.minimum(offsets[:-1], max(len(flags) - 1, 0))
    counts = np.add.reduceat(flags.astype(np.int64), starts) if len(flags) else np.zeros(n, np.int64)
    counts[offsets[:-1] == offsets[1:]] = 0  # reduceat gives the next element for an empty list
    letters = np.where(flags == 1, ord("i"), ord("f")).astype(np.uint8)
    patterns = pa.Array.from_buffers(pa.string(), n, [None, pa.py_buffer(offsets.astype(np.int32)),
                                                       pa.py_buffer(letters)])
    joined = pc.binary_join_element_wise(pa.scalar(name + ":"), patterns, "")
    return pc.if_else(pa.array(counts > 0), joined, pa.scalar(None, pa.string()))


def _mark_lists(marks: list[pa.Array], n: int) -> pa.Array:
    """`_json_types`: per record the list of its fields' marks (in field order), null where it has none."""
    m = len(marks)
    together = pa.concat_arrays([a.cast(pa.string()) for a in marks])
    order = np.arange(n * m).reshape(m, n).T.ravel()
    interleaved = together.take(pa.array(order))
    present = interleaved.is_valid().to_numpy(zero_copy_only=False)
    counts = present.reshape(n, m).sum(axis=1)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    values = interleaved.filter(pa.array(present))
    lists = pa.ListArray.from_arrays(pa.array(offsets), values, type=pa.list_(pa.field("l", pa.string())))
    return pc.if_else(pa.array(counts > 0), lists, pa.scalar(None, lists.type))
