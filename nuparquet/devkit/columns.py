"""A converted table's Arrow columns as row getters: each value of row i as the Python value `json.load` gave.

The table is read with the system allocator and kept in its row-group chunks (`read_table`); each column becomes a
function of the row number (`getter`) that decodes from the Arrow buffers through numpy views, a chunked column
chunk by chunk; repeated strings are dictionary-encoded (`shared_strings`) so their records share one Python string.
`Columns` rebuilds whole records with export-json's facts (key order, record layouts, JSON types); `TokenIndex`
finds the row of a token in a sorted copy of the token column.

Longer than our ~300-line norm on purpose: every JSON type a converted column can hold (and the facts that
rebuild a record's key order and literals) is one decision table, read together.
"""

from __future__ import annotations

import bisect
import json
from collections.abc import Callable
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as pads
import pyarrow.parquet as pq

from nuparquet.sources import table_layouts
from nuparquet.sources.json_records import to_records

Getter = Callable[[int], Any]
# A string column with at most one distinct value per this many rows is decoded through a dictionary: one Python
# string per distinct value, shared by every record (sample_token, instance_token, calibrated_sensor_token, ...).
SHARED_STRINGS_RATIO = 4


def read_table(files: list[str], columns: list[str] | None = None, filesystem=None) -> pa.Table:
    """The rows of a dataset's Parquet files in order (all columns, or `columns` that exist), a chunk per row group;
    `filesystem`: the pyarrow FileSystem of an object-store output (None: local files).

    Read with the system allocator, and left in its chunks (the getters index them): both keep the resident memory
    near the data's size, where mimalloc's caches and a concatenated copy would double it for the large tables."""
    if not files:
        raise ValueError("no Parquet files")
    present = pq.read_schema(files[0], filesystem=filesystem).names
    wanted = None if columns is None else [c for c in columns if c in present]
    pool = pa.system_memory_pool()
    tables = [pads.dataset(f, format="parquet", filesystem=filesystem).to_table(columns=wanted, memory_pool=pool)
              for f in files]
    return tables[0] if len(tables) == 1 else pa.concat_tables(tables)


def single_chunk(array: pa.Array | pa.ChunkedArray) -> pa.Array:
    """One contiguous array (pyarrow's combine_chunks copies even a single chunk)."""
    if isinstance(array, pa.ChunkedArray):
        return array.chunk(0) if array.num_chunks == 1 else array.combine_chunks()
    return array


# --- one column as a function of the row number ----------------------------------------------------------------

def getter(array: pa.Array | pa.ChunkedArray, *, empty_list: bool = False, json_text: bool = False,
           share_strings: bool = True) -> Getter:
    """`f(i)`: row i of `array` as the Python value `json.load` gave (None for null, or [] with `empty_list`;
    `json_text`: the column holds raw JSON text, parsed). Reads Arrow buffers through numpy views; a chunked
    column is read chunk by chunk (row groups of one size: the chunk is i // size)."""
    if isinstance(array, pa.ChunkedArray):
        if array.num_chunks != 1:
            return _chunked_getter(array, empty_list=empty_list, json_text=json_text, share_strings=share_strings)
        array = array.chunk(0)
    if json_text:
        text = getter(array, share_strings=False)
        return lambda i: None if (v := text(i)) is None else json.loads(v)
    value = _value_getter(array, share_strings)
    if not array.null_count:
        return value
    valid = array.is_valid().to_numpy(zero_copy_only=False)
    if empty_list:
        return lambda i: value(i) if valid[i] else []
    return lambda i: value(i) if valid[i] else None


def nested(array: pa.ChunkedArray, shape: tuple[int, int]) -> pa.ChunkedArray:
    """A flat fixed-size list column (camera_intrinsic's [9]) as the JSON nests it: rows of `shape[1]` values
    (`Field.json_shape`); nulls kept."""
    rows, width = shape

    def one(chunk: pa.FixedSizeListArray) -> pa.Array:
        values = chunk.values.slice(chunk.offset * rows * width, len(chunk) * rows * width)
        inner = pa.FixedSizeListArray.from_arrays(values, width)
        return pa.FixedSizeListArray.from_arrays(inner, rows, mask=chunk.is_null() if chunk.null_count else None)

    return pa.chunked_array([one(chunk) for chunk in array.chunks],
                            pa.list_(pa.list_(array.type.value_type, width), rows))


def _chunked_getter(array: pa.ChunkedArray, **options) -> Getter:
    chunks = [chunk for chunk in array.chunks if len(chunk)]
    if not chunks:
        return lambda i: [][i]  # IndexError, as an empty list
    parts = [getter(chunk, **options) for chunk in chunks]
    size = len(chunks[0])
    if all(len(chunk) == size for chunk in chunks[:-1]):
        return lambda i: parts[i // size](i % size)
    starts = np.cumsum([0] + [len(chunk) for chunk in chunks]).tolist()
    return lambda i: parts[(c := bisect.bisect_right(starts, i) - 1)](i - starts[c])


def shared_strings(column: pa.ChunkedArray) -> pa.ChunkedArray:
    """`column` dictionary-encoded when it repeats its values (at most one distinct value per
    `SHARED_STRINGS_RATIO` rows): its records then share one Python string per value, and Arrow holds small codes
    instead of the strings."""
    kind = column.type
    if not (pa.types.is_string(kind) or pa.types.is_large_string(kind)) or len(column) < 64:
        return column
    if pc.count_distinct(column).as_py() * SHARED_STRINGS_RATIO > len(column):
        return column
    return pc.dictionary_encode(column, memory_pool=pa.system_memory_pool())


def _value_getter(array: pa.Array, share_strings: bool) -> Getter:
    kind = array.type
    if pa.types.is_dictionary(kind):
        values = array.dictionary.to_pylist()
        codes = array.indices.to_numpy(zero_copy_only=False)
        return lambda i: values[codes[i]]
    if pa.types.is_string(kind) or pa.types.is_large_string(kind):
        return _string_getter(array)
    if pa.types.is_boolean(kind):
        flags = array.to_numpy(zero_copy_only=False)
        return lambda i: bool(flags[i])
    if pa.types.is_integer(kind):
        numbers = array.fill_null(0).to_numpy() if array.null_count else array.to_numpy()
        return lambda i: int(numbers[i])
    if pa.types.is_floating(kind):
        numbers = array.fill_null(0.0).to_numpy() if array.null_count else array.to_numpy()
        return lambda i: float(numbers[i])
    if pa.types.is_fixed_size_list(kind) and _is_numeric_block(kind):
        block = fixed_block(array)
        return lambda i: block[i].tolist()
    if pa.types.is_list(kind) or pa.types.is_large_list(kind):
        offsets = array.offsets.to_numpy()
        values = array.values
        element = getter(shared_strings(pa.chunked_array([values])) if share_strings else values)
        return lambda i: [element(j) for j in range(offsets[i], offsets[i + 1])]
    return lambda i: array[i].as_py()  # anything else (structs): pyarrow's own conversion


def _string_getter(array: pa.Array) -> Getter:
    """Row i of a (large_)string array, decoded from its data buffer (by arithmetic when every value has the same
    length, as tokens do: no offset lookups)."""
    width = np.int64 if pa.types.is_large_string(array.type) else np.int32
    offsets = np.frombuffer(array.buffers()[1], dtype=width)[array.offset:array.offset + len(array) + 1]
    data = array.buffers()[2]
    raw = memoryview(data) if data is not None else memoryview(b"")
    lengths = np.diff(offsets)
    if len(lengths) and (lengths == lengths[0]).all():
        base, size = int(offsets[0]), int(lengths[0])
        return lambda i: str(raw[base + size * i:base + size * i + size], "utf-8")
    return lambda i: str(raw[offsets[i]:offsets[i + 1]], "utf-8")


def _is_numeric_block(kind: pa.DataType) -> bool:
    while pa.types.is_fixed_size_list(kind):
        kind = kind.value_type
    return pa.types.is_integer(kind) or pa.types.is_floating(kind)


def fixed_block(array: pa.Array | pa.ChunkedArray) -> np.ndarray:
    """(N, k) or (N, k, m) numpy view of a fixed-size list array of numbers (nulls hold zeros; a chunked array is
    concatenated)."""
    if isinstance(array, pa.ChunkedArray):
        if array.num_chunks != 1:
            return np.concatenate([fixed_block(chunk) for chunk in array.chunks]) if array.num_chunks else \
                fixed_block(pa.array([], array.type))
        array = array.chunk(0)
    shape = [len(array)]
    values = array
    while pa.types.is_fixed_size_list(values.type):
        size = values.type.list_size
        shape.append(size)
        # the child values of this slice (`.values` ignores the slice; `flatten()` would drop the null slots)
        values = values.values.slice(values.offset * size, len(values) * size)
    return values.to_numpy(zero_copy_only=False).reshape(shape)


def token_bytes(array: pa.Array | pa.ChunkedArray) -> np.ndarray:
    """(N,) numpy bytes array of a string column (a zero-copy view of one chunk when every value has the same
    length, as nuScenes' 32-character tokens do; nulls as b"")."""
    if isinstance(array, pa.ChunkedArray):
        if array.num_chunks != 1:
            parts = [token_bytes(chunk) for chunk in array.chunks if len(chunk)]
            width = max((p.dtype.itemsize for p in parts), default=1)
            return np.concatenate([p.astype(f"S{width}") for p in parts]) if parts else np.array([], "S1")
        array = array.chunk(0)
    if pa.types.is_dictionary(array.type):
        return token_bytes(array.dictionary)[array.indices.fill_null(0).to_numpy()] if len(array) else np.array([], "S1")
    if array.null_count == 0 and len(array) and pa.types.is_string(array.type):
        offsets = np.frombuffer(array.buffers()[1], dtype=np.int32)[array.offset:array.offset + len(array) + 1]
        width = int(offsets[1] - offsets[0])
        if width > 0 and np.all(np.diff(offsets) == width):
            data = np.frombuffer(array.buffers()[2], dtype=np.uint8)[offsets[0]:offsets[-1]]
            return data.view(f"S{width}")
    return np.array([(v or "").encode() for v in array.to_pylist()] or [b""])[:len(array)]


class TokenIndex:
    """Row numbers of tokens: a sorted copy of the token column, searched in O(log N)."""

    def __init__(self, tokens: np.ndarray):
        order = np.argsort(tokens, kind="stable")
        self.order = order.astype(np.int32) if len(order) < 2**31 else order
        self.sorted = tokens[order]

    def find(self, token: str) -> int:
        """The row of `token`; KeyError(token) when absent (as the devkit's dict lookup)."""
        if type(token) is not str:
            raise KeyError(token)
        key = token.encode()
        j = int(np.searchsorted(self.sorted, key))
        if j < len(self.sorted) and self.sorted[j] == key:
            return int(self.order[j])
        raise KeyError(token)

    def find_all(self, tokens: np.ndarray) -> np.ndarray:
        """(M,) int64 rows of the bytes `tokens`, -1 where absent."""
        if not len(self.sorted):
            return np.full(len(tokens), -1, dtype=np.int64)
        j = np.minimum(np.searchsorted(self.sorted, tokens), len(self.sorted) - 1)
        return np.where(self.sorted[j] == tokens, self.order[j], -1).astype(np.int64)


# --- one table's columns -------------------------------------------------------------------------------------------

class Columns:
    """One converted table in Arrow, and how its records are rebuilt (export-json's facts).

    Args:
        table: the table's columns (with the hidden `_layout` / `_json_types` columns when it has them).
        key_order: the JSON key order (the manifest's `tables[name].key_order`).
        layouts: the record layouts (`tables[name].layouts`), [] when every record has `key_order`.
        json_fields: fields kept as raw JSON text.
        empty_list_fields: fields whose null is the JSON `[]` (camera_intrinsic).
    """

    def __init__(self, table: pa.Table, key_order: list[str], layouts: list[list[str]] | None = None,
                 json_fields=(), empty_list_fields=()):
        names = table.column_names
        for k in key_order:  # repeated strings (foreign keys, channels) kept once, as dictionaries
            if k not in ("token", "prev", "next") and k not in json_fields:
                table = table.set_column(names.index(k), k, shared_strings(table.column(k)))
        self.table = table
        self.keys = list(key_order)
        self.length = table.num_rows
        self._getters = [getter(table.column(k), empty_list=k in empty_list_fields, json_text=k in json_fields,
                                share_strings=k != "token")
                         for k in self.keys]
        self._layouts = layouts or [self.keys]
        layout = table.column(table_layouts.LAYOUT) if table_layouts.LAYOUT in names else None
        self._layout_ids = layout.to_numpy() if layout is not None else None
        marks = table.column(table_layouts.JSON_TYPES) if table_layouts.JSON_TYPES in names else None
        self._marks = getter(marks, share_strings=False) if marks is not None else None
        self._int_columns = {f.name for f in table.schema if pa.types.is_integer(f.type)}
        self._token = getter(table.column("token"), share_strings=False) if "token" in names else None
        self._index: TokenIndex | None = None

    def record(self, i: int) -> dict:
        """Record i as `json.load` gave it."""
        record = dict(zip(self.keys, [value(i) for value in self._getters]))
        if self._layout_ids is not None:
            layout = self._layout_ids[i]
            if layout:  # the record's own keys in its own order; a field it lacks stays absent
                record = {k: record[k] for k in self._layouts[layout]}
        if self._marks is not None:
            marks = self._marks(i)
            if marks:
                table_layouts.restore(record, marks, self._int_columns)
        return record

    def token(self, i: int) -> str:
        return self._token(i)

    @property
    def index(self) -> TokenIndex:
        if self._index is None:
            self._index = TokenIndex(self.token_bytes("token"))
        return self._index

    def token_bytes(self, name: str) -> np.ndarray:
        """(N,) bytes of string column `name` (`token_bytes`)."""
        return token_bytes(self.table.column(name))

    def numpy(self, name: str) -> np.ndarray:
        """Column `name` as numpy: (N,) for scalars, (N, k) for fixed-size lists of numbers."""
        column = self.table.column(name)
        if pa.types.is_fixed_size_list(column.type):
            return fixed_block(column)
        return column.to_numpy()

    def getter(self, name: str) -> Getter:
        return getter(self.table.column(name))

    def tokens_where(self, field: str, query) -> list[str] | None:
        """Tokens of the rows whose stored `field` == `query` as Python compares them, or None when the column
        cannot say (the field absent from some records, held as JSON text or a list, nulls, an unusual query)."""
        if field not in self.keys or self._layout_ids is not None or field not in self.table.column_names:
            return None
        column = self.table.column(field)
        if pa.types.is_dictionary(column.type):
            column = column.cast(column.type.value_type)
        kind = column.type
        if column.null_count or not (pa.types.is_string(kind) or pa.types.is_large_string(kind)
                                     or pa.types.is_integer(kind) or pa.types.is_floating(kind)
                                     or pa.types.is_boolean(kind)):
            return None
        text = pa.types.is_string(kind) or pa.types.is_large_string(kind)
        if query is None or isinstance(query, str) != text:  # a string never equals a number, nor None anything
            return [] if query is None or type(query) in (str, int, float, bool) else None
        if type(query) not in (str, int, float, bool):
            return None
        if text:
            mask = pc.equal(column, query).to_numpy(zero_copy_only=False)
        else:
            mask = column.to_numpy(zero_copy_only=False) == query  # NaN equals nothing, True == 1, 1 == 1.0
        return [self.token(i) for i in np.flatnonzero(mask).tolist()]


class RecordColumns:
    """A table typed by inference at conversion (an extra table of the version folder, e.g. image_annotations):
    its records rebuilt all at once by `nuparquet.sources.json_records.to_records`, as export-json writes them."""

    def __init__(self, table: pa.Table, facts: dict):
        self.table = table
        self.length = table.num_rows
        self.keys = list(facts["keys"])
        self._records = to_records(table.to_pylist(), facts["keys"], facts.get("json_fields", []),
                                   facts.get("int_values", {}), facts.get("key_orders", {}))
        self._index: TokenIndex | None = None

    def record(self, i: int) -> dict:
        return self._records[i]

    def tokens_where(self, field: str, query) -> None:
        return None  # compared record by record

    def token(self, i: int) -> str:
        return self._records[i]["token"]

    @property
    def index(self) -> TokenIndex:
        if self._index is None:
            self._index = TokenIndex(token_bytes(self.table.column("token")))
        return self._index
