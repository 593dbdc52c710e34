"""One JSON table file through the compiled kernel (`sources/json_scan.py`), window by window: the raw columns of
every record as Arrow arrays (strings, integers, number texts and their literal kinds, lists), the JSON kind of
every value, the records' key orders and where each record starts. Typing and checking them against the schema is
`sources/table_typing.py`'s work.

Longer than our ~300-line norm on purpose: the window loop, the growth of the kernel's streams and the Arrow arrays
made of them share one file's state and the kernel's conventions (`json_scan`'s stream layout).

Memory stays bounded whatever the file: the file is read `WINDOW_BYTES` at a time (a record longer than a window
grows it, up to `MAX_RECORD_BYTES`), the kernel's streams hold one window's values, and a string value over
`MAX_STRING_BYTES` is refused without being copied.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from nuparquet.errors import EnvironmentFault
from nuparquet.problems import Problem
from nuparquet.schemas import Field

try:
    from nuparquet.sources import json_scan as k
except ImportError as exc:  # pragma: no cover - numba is a declared dependency
    raise EnvironmentFault(f"the JSON table reader needs numba, which cannot be loaded here: {exc}") from exc

WINDOW_BYTES = 16 * 2**20
MAX_STRING_BYTES = 64 * 2**20  # the longest string value a table may hold (docs/CONTRACTS.md lists the limits)
MAX_RECORD_BYTES = 256 * 2**20  # the longest record
MAX_KEY_BYTES = 4096  # the longest field name
MAX_FIELDS = 1000  # distinct field names of one table

_ERRORS = {
    k.E_EOF: "the file ends before the JSON array is closed",
    k.E_VALUE: "expected a JSON value",
    k.E_DELIM_ARRAY: "expected ',' or ']'",
    k.E_DELIM_OBJECT: "expected ',' or '}'",
    k.E_KEY: "expected a field name in double quotes",
    k.E_COLON: "expected ':'",
    k.E_CONTROL: "a control character inside a string (JSON needs it escaped)",
    k.E_ESCAPE: "an invalid escape in a string",
    k.E_UTF8: "bytes that are not UTF-8",
    k.E_SURROGATE: "a \\u escape of half a surrogate pair (no UTF-8 text can hold it)",
    k.E_NUMBER: "a number that is not JSON (digits must follow '.' and 'e')",
    k.E_EXTRA_DATA: "more data after the JSON array",
    k.E_DEPTH: f"a value nested deeper than {k.MAX_DEPTH} levels",
    k.E_TRAILING_COMMA: "a trailing comma",
    k.E_LAYOUTS: f"more than {k.MAX_LAYOUTS:,} different key orders in one table",
}


@dataclass
class Column:
    """One field's raw columns: per record `values` (strings, int64, raw JSON text, or a list array) and, for
    integers and numbers, `texts` (the literal where it is not an int64) and `flags` (1 = an integer literal, per
    list element)."""

    field: Field | None  # None: a field the schema does not know
    name: str
    cls: int
    values: list = field(default_factory=list)  # Arrow arrays, one per window
    texts: list = field(default_factory=list)
    flags: list = field(default_factory=list)  # numpy uint8, one per window


@dataclass
class Scanned:
    columns: dict[str, Column]  # by name, schema fields first, then extras in order of first appearance
    kinds: np.ndarray  # (records, fields) uint8: json_scan kinds, columns in `columns` order
    starts: np.ndarray  # (records,) int64: file offset of each record
    layout_of: np.ndarray  # (records,) int64: index into `layouts`; -1 - kind for a record that is not an object
    layouts: list[list[str]]  # key orders seen, in order of first appearance
    layout_counts: list[int]
    duplicates: np.ndarray  # (records,) int64: 1 + the column of the record's first repeated key, or 0


def _class(f: Field) -> int:
    if f.type == "string":
        return k.C_STRING
    if f.type == "int64":
        return k.C_INT
    if f.type == "bool":
        return k.C_BOOL
    if f.type == "list<string>":
        return k.C_STRINGS
    if f.type.startswith("fixed_size_list"):
        return k.C_MATRIX if f.nested_in_json else k.C_FLOATS
    raise ValueError(f"no JSON reading for schema type {f.type!r}")


class _Region:
    """Streams of one dtype as regions of one array (no list of arrays in the kernel's inner loops): stream s is
    `array[base[s]:base[s] + cap[s]]`, its first `count[s]` items filled. The kernel gets `as_tuple()`."""

    def __init__(self, dtype):
        self.array = np.empty(0, dtype)
        self.base = np.zeros(0, np.int64)
        self.cap = np.zeros(0, np.int64)
        self.count = np.zeros(0, np.int64)

    def add(self, size: int) -> int:
        self.count = np.append(self.count, 0)
        self._layout(np.append(self.cap, size))
        return len(self.cap) - 1

    def grow(self, sid: int, need: int) -> None:
        caps = self.cap.copy()
        caps[sid] = max(2 * caps[sid], int(self.count[sid]) + need, 1024)
        self._layout(caps)

    def _layout(self, caps: np.ndarray) -> None:
        base = np.concatenate([[0], np.cumsum(caps)[:-1]]).astype(np.int64)
        array = np.empty(int(caps.sum()), self.array.dtype)
        for sid in range(len(self.base)):  # the filled part of each existing stream
            n = int(self.count[sid])
            array[base[sid]:base[sid] + n] = self.array[self.base[sid]:self.base[sid] + n]
        self.array, self.base, self.cap = array, base, caps.astype(np.int64)

    def view(self, sid: int) -> np.ndarray:
        return self.array[self.base[sid]:self.base[sid] + self.count[sid]]

    def as_tuple(self):
        return self.array, self.base, self.cap, self.count


class _Streams:
    """The kernel's output arrays: byte streams, int64 streams, per-record arrays; grown on demand."""

    def __init__(self, records: int):
        self.u8 = _Region(np.uint8)
        self.i64 = _Region(np.int64)
        self.records = records
        self.rec = np.zeros((records, 0), np.int64)  # per-record slots (offsets, integer values)
        self.kinds = np.zeros((records, 0), np.uint8)
        self.starts = np.zeros(records, np.int64)
        self.layout_of = np.zeros(records, np.int64)
        self.dup = np.zeros(records, np.int64)

    def add_slot(self) -> int:
        self.rec = np.concatenate([self.rec, np.zeros((self.records, 1), np.int64)], axis=1)
        return self.rec.shape[1] - 1

    def add_field(self) -> None:
        self.kinds = np.concatenate([self.kinds, np.zeros((self.records, 1), np.uint8)], axis=1)

    def grow(self, sid: int, which: int, need: int) -> None:
        if which == 0:  # bytes: room for the whole record at once
            self.u8.grow(sid, need)
        else:
            self.i64.grow(sid, 0)

    def grow_records(self) -> None:
        n = 2 * self.records
        self.kinds = np.concatenate([self.kinds, np.zeros_like(self.kinds)])
        self.rec = np.concatenate([self.rec, np.zeros_like(self.rec)])
        self.starts, self.layout_of, self.dup = (np.resize(a, n) for a in (self.starts, self.layout_of, self.dup))
        self.records = n


class _Fields:
    """The fields the kernel knows (schema fields, then extras as they appear): its `spec` and `names` arrays."""

    def __init__(self, schema_fields: tuple[Field, ...], streams: _Streams, window: int):
        self.streams = streams
        self.window = window
        self.columns: dict[str, Column] = {}
        self.spec = np.zeros((0, 8), np.int64)
        self.spellings: list[tuple[int, bytes]] = []
        for f in schema_fields:
            self.add(f.name, f, _class(f))

    def add(self, name: str, f: Field | None, cls: int, spelling: bytes | None = None) -> None:
        s = self.streams
        row = np.full(8, -1, np.int64)
        row[k.CLASS] = cls
        guess = max(1024, self.window // 8)
        if cls in (k.C_STRING, k.C_RAW, k.C_INT):
            row[k.DATA] = s.u8.add(guess if cls != k.C_INT else 1024)
            row[k.OFFSETS] = s.add_slot()
        if cls == k.C_INT:
            row[k.VALUES] = s.add_slot()
        if cls in (k.C_FLOATS, k.C_MATRIX, k.C_STRINGS):
            row[k.DATA] = s.u8.add(guess)
            row[k.ELEMENTS] = s.i64.add(guess // 4)
            row[k.OFFSETS] = s.add_slot()
            if cls != k.C_STRINGS:
                row[k.FLAGS] = s.u8.add(guess // 4)
        self.spec = np.vstack([self.spec, row])
        s.add_field()
        self.columns[name] = Column(f, name, cls)
        self.spellings.append((len(self.columns) - 1, spelling if spelling is not None else name.encode()))

    def alias(self, index: int, spelling: bytes) -> None:
        self.spellings.append((index, spelling))

    def names(self) -> np.ndarray:
        width = 2 + max((len(b) for _, b in self.spellings), default=0)
        names = np.zeros((len(self.spellings), width), np.int64)
        for row, (index, spelling) in enumerate(self.spellings):
            names[row, 0], names[row, 1] = index, len(spelling)
            names[row, 2:2 + len(spelling)] = np.frombuffer(spelling, np.uint8)
        return names


def scan_table(path: Path, schema_fields: tuple[Field, ...], start: int) -> tuple[Scanned | None, list[Problem]]:
    """Scan `path` from byte `start` (just after the opening '['). (Scanned, []) or (None, [the problem])."""
    file = path.name
    window = WINDOW_BYTES
    streams = _Streams(max(1024, window // 256))
    fields = _Fields(schema_fields, streams, window)
    names = fields.names()
    io = np.zeros(11, np.int64)
    io[k.MAX_STRING] = MAX_STRING_BYTES
    io[k.STATE] = k.S_FIRST
    layouts = np.zeros((256, len(fields.columns) + 1), np.int64)
    layout_counts = np.zeros(256, np.int64)
    by_hash = np.zeros((2 * (k.MAX_LAYOUTS + 1), 2), np.int64)  # open addressing: layout hash -> first layout id
    kinds, starts, layout_of, dups = [], [], [], []
    buf = np.empty(window, np.uint8)
    filled = 0
    offset = start  # file offset of buf[0]
    with path.open("rb") as source:
        source.seek(start)
        final = False
        while True:
            if not final:
                got = source.readinto(memoryview(buf)[filled:])
                filled += got
                final = filled < len(buf)  # a regular file fills the buffer unless it ends
            io[k.POS], io[k.RECORDS], io[k.FILE_OFFSET] = 0, 0, offset
            while True:
                n_streams = len(streams.u8.count) + len(streams.i64.count)
                k.scan(buf, filled, final, io, fields.spec, names, streams.u8.as_tuple(), streams.i64.as_tuple(),
                       streams.rec, streams.kinds, streams.starts, streams.layout_of, layouts, layout_counts, by_hash,
                       streams.dup, np.empty(n_streams + len(fields.columns) + 1, np.int64),
                       np.empty(k.MAX_DEPTH, np.uint8), np.zeros(len(fields.columns), np.bool_))
                status = io[k.STATUS]
                if status == k.FULL:
                    if io[k.ARG0] < 0:
                        streams.grow_records()
                    else:
                        streams.grow(int(io[k.ARG0]), int(io[k.ARG1]), filled - int(io[k.POS]))
                elif status == k.NEW_KEY:
                    before = sum(len(a) for a in layout_of)  # records of earlier windows: null in a new field
                    problem = _new_key(buf, int(io[k.ARG0] - offset), int(io[k.ARG1] - offset), fields, file,
                                       before, int(io[k.RECORDS]))
                    if problem is not None:
                        return None, [problem]
                    last = list(fields.columns.values())[-1]
                    if before and not last.values:
                        last.values.append(pa.nulls(before, pa.string()))
                    names = fields.names()
                    if layouts.shape[1] < len(fields.columns) + 1:
                        layouts = np.concatenate([layouts, np.zeros((len(layouts), 1), np.int64)], axis=1)
                elif status == k.ERROR and io[k.ERR_CODE] == k.E_LAYOUTS and len(layouts) < k.MAX_LAYOUTS:
                    layouts = np.concatenate([layouts, np.zeros_like(layouts)])
                    layout_counts = np.concatenate([layout_counts, np.zeros_like(layout_counts)])
                else:
                    break
            if status == k.ERROR:
                return None, [_grammar_problem(path, int(offset + io[k.ERR_POS]), int(io[k.ERR_CODE]))]
            records = int(io[k.RECORDS])
            _emit(fields, streams, records)
            kinds.append(streams.kinds[:records].copy())
            starts.append(streams.starts[:records].copy())
            layout_of.append(streams.layout_of[:records].copy())
            dups.append(streams.dup[:records].copy())
            if status == k.DONE:
                break
            # MORE: keep the cut record, read on; a record longer than the window grows it
            pos = int(io[k.POS])
            if pos == 0 and filled == len(buf):
                if len(buf) >= MAX_RECORD_BYTES:
                    index = sum(len(a) for a in kinds)
                    return None, [Problem(file, f"record is longer than {MAX_RECORD_BYTES // 2**20} MiB (the longest "
                                                "a table may hold)", index)]
                buf = np.concatenate([buf, np.empty(len(buf), np.uint8)])
            else:
                buf[:filled - pos] = buf[pos:filled]
                filled -= pos
                offset += pos
    n_fields = len(fields.columns)
    kinds = np.concatenate([np.pad(a, ((0, 0), (0, n_fields - a.shape[1]))) for a in kinds])
    n_layouts = int(io[k.LAYOUTS])
    column_names = list(fields.columns)
    layout_names = [[column_names[i] for i in layouts[j, 1:1 + layouts[j, 0]]] for j in range(n_layouts)]
    return Scanned(fields.columns, kinds, np.concatenate(starts), np.concatenate(layout_of), layout_names,
                   layout_counts[:n_layouts].tolist(), np.concatenate(dups)), []


def _new_key(buf: np.ndarray, begin: int, end: int, fields: _Fields, file: str, before: int, r: int) -> Problem | None:
    """Register the key at buf[begin:end] (its raw spelling, escapes included) as a new field or an alias."""
    raw = bytes(buf[begin:end])
    if len(raw) > MAX_KEY_BYTES:
        return Problem(file, f"a field name is longer than {MAX_KEY_BYTES:,} bytes", before + r)
    name = json.loads(b'"' + raw + b'"')
    names = list(fields.columns)
    if name in names:
        fields.alias(names.index(name), raw)
        return None
    if len(names) >= MAX_FIELDS:
        return Problem(file, f"more than {MAX_FIELDS:,} different field names", before + r)
    fields.add(name, None, k.C_RAW, raw)
    return None


def _emit(fields: _Fields, streams: _Streams, records: int) -> None:
    """The window's values as Arrow arrays (appended to each column), then the streams emptied."""
    kinds = streams.kinds[:records]
    rec = streams.rec[:records]
    for j, (name, column) in enumerate(fields.columns.items()):
        row = fields.spec[j]
        cls = column.cls
        kind = kinds[:, j]
        if cls in (k.C_STRING, k.C_RAW):
            ok = kind == k.STRING if cls == k.C_STRING else ((kind != k.ABSENT) & (kind != k.TOO_LONG))
            column.values.append(_strings(streams.u8.view(row[k.DATA]), rec[:, row[k.OFFSETS]], ok))
        elif cls == k.C_INT:
            column.values.append(pa.array(rec[:, row[k.VALUES]].copy(), pa.int64(), mask=kind != k.INT))
            literal = (kind == k.FLOAT) | (kind == k.BIGINT)
            column.texts.append(_strings(streams.u8.view(row[k.DATA]), rec[:, row[k.OFFSETS]], literal)
                                if literal.any() else pa.nulls(records, pa.string()))
        elif cls == k.C_BOOL:
            column.values.append(pa.array(kind == k.TRUE, pa.bool_(), mask=(kind != k.TRUE) & (kind != k.FALSE)))
        else:
            ends = streams.i64.view(row[k.ELEMENTS])
            offsets = pa.array(np.concatenate([[0], rec[:, row[k.OFFSETS]]]).astype(np.int32))
            elements = _strings(streams.u8.view(row[k.DATA]), ends, None)
            if cls != k.C_STRINGS:
                elements = pc.cast(elements, pa.float64())
                column.flags.append(streams.u8.view(row[k.FLAGS]).copy())
            column.values.append(pa.ListArray.from_arrays(offsets, elements, mask=pa.array(kind != k.LIST_OK)))
    streams.u8.count[:] = 0
    streams.i64.count[:] = 0


def _strings(data: np.ndarray, ends: np.ndarray, valid: np.ndarray | None) -> pa.Array:
    """A string array over the bytes `data` with per-value end offsets `ends` (nulls where not `valid`)."""
    size = int(ends[-1]) if len(ends) else 0
    buffer = pa.py_buffer(data[:size].copy())
    offsets = pa.py_buffer(np.concatenate([[0], ends]).astype(np.int32))
    if valid is None or valid.all():
        return pa.Array.from_buffers(pa.string(), len(ends), [None, offsets, buffer])
    bitmap = pa.py_buffer(np.packbits(valid, bitorder="little"))
    return pa.Array.from_buffers(pa.string(), len(ends), [bitmap, offsets, buffer], int((~valid).sum()))


def _grammar_problem(path: Path, pos: int, code: int) -> Problem:
    line, column = line_column(path, pos)
    return Problem(path.name, f"not valid JSON at line {line}, column {column}: {_ERRORS[code]}")


def line_column(path: Path, pos: int) -> tuple[int, int]:
    """1-based line and column (in characters, as Python's json counts them) of byte `pos` of `path`."""
    lines, line_start, at = 0, 0, 0
    with path.open("rb") as f:
        while at < pos:
            part = f.read(min(WINDOW_BYTES, pos - at))
            if not part:
                break
            lines += part.count(b"\n")
            last = part.rfind(b"\n")
            if last != -1:
                line_start = at + last + 1
            at += len(part)
        f.seek(line_start)
        text = f.read(pos - line_start)
    return lines + 1, len(text.decode("utf-8", errors="replace")) + 1
