"""The converted source tables (`tables/<name>`) as the devkit's lists of dicts, each record built when first asked for.

The devkit `json.load`s every table at start-up and keeps a dict per record. Here a table's Parquet files are read
on first use into Arrow buffers (no Python object per value: `Columns`), and a record is built from them when it is
first asked for, by index, by token or by iteration (`Table`), then kept: the same dict object comes back every
time, as the devkit's list element does, so a record changed by its user stays changed.

A record is what `json.load` gave: the keys in the record's own order, absent fields absent, integers and floats
as they were written, `[]` for a null camera intrinsic. These facts come from the conversion exactly as
`nuparquet export-json` uses them (the manifest's `key_order`, `layouts`, `json_fields`; the hidden `_layout` and
`_json_types` columns, `nuparquet.sources.table_layouts`).

Lookups by token use a sorted copy of the token column (numpy, built on first lookup): a first lookup costs a
binary search and the record's construction; a record already built is one dict lookup away.
"""

from __future__ import annotations

import bisect
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as pads
import pyarrow.parquet as pq

from nuparquet.devkit.errors import ReadOnly
from nuparquet.errors import FormatError
from nuparquet.sources import table_layouts
from nuparquet.sources.json_records import to_records

Getter = Callable[[int], Any]
# A string column with at most one distinct value per this many rows is decoded through a dictionary: one Python
# string per distinct value, shared by every record (sample_token, instance_token, calibrated_sensor_token, ...).
SHARED_STRINGS_RATIO = 4


def read_table(files: list[str], columns: list[str] | None = None) -> pa.Table:
    """The rows of a dataset's Parquet files in order (all columns, or `columns` that exist), a chunk per row group.

    Read with the system allocator, and left in its chunks (the getters index them): both keep the resident memory
    near the data's size, where mimalloc's caches and a concatenated copy would double it for the large tables."""
    if not files:
        raise ValueError("no Parquet files")
    present = pq.read_schema(files[0]).names
    wanted = None if columns is None else [c for c in columns if c in present]
    pool = pa.system_memory_pool()
    tables = [pads.dataset(f, format="parquet").to_table(columns=wanted, memory_pool=pool) for f in files]
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

    def token(self, i: int) -> str:
        return self._records[i]["token"]

    @property
    def index(self) -> TokenIndex:
        if self._index is None:
            self._index = TokenIndex(token_bytes(self.table.column("token")))
        return self._index


# --- the devkit's list of dicts --------------------------------------------------------------------------------

class Table(Sequence):
    """One devkit table (`nusc.sample`, ...): a read-only sequence of dicts in file order.

    Indexing (ints, negative ints, slices: a slice is a list), `len`, iteration and `in` behave as on the devkit's
    list; records are built on first access and kept (`by_token` holds the ones built so far). Writes (`append`,
    item assignment, ...) raise `ReadOnly`; the records themselves are plain dicts and may be changed.

    Args:
        name: the table's name.
        length: its number of records (from the manifest: counting needs no read).
        load: reads the table (`Columns`) on first use.
        decorate: `decorate(record, i)` adds the devkit's reverse-index fields to a new record.
        keep: keep each record once built (the devkit's semantics: one dict per record, changes stay); False builds
            a new dict on every access, holding no records (lean on memory, ~20x slower per repeated access).
    """

    def __init__(self, name: str, length: int, load: Callable[[], Columns | RecordColumns],
                 decorate: Callable[[dict, int], None] | None = None, keep: bool = True):
        self.name = name
        self._length = length
        self._load = load
        self._decorate = decorate
        self._keep = keep
        self._columns: Columns | RecordColumns | None = None
        self._by_index: list | None = None
        self.by_token: dict[str, dict] = {}

    @property
    def columns(self) -> Columns | RecordColumns:
        if self._columns is None:
            self._columns = self._load()
            if self._columns.length != self._length:
                raise ValueError(f"tables/{self.name} has {self._columns.length} rows, the manifest says {self._length}")
        return self._columns

    @property
    def loaded(self) -> bool:
        return self._columns is not None

    def __len__(self) -> int:
        return self._length

    def record(self, i: int) -> dict:
        """Record i (0 <= i < len), built once (each time it is asked for, when the table does not keep records)."""
        rows = self._by_index
        if rows is None:
            rows = self._by_index = [None] * self._length if self._keep else ()
        record = rows[i] if self._keep else None
        if record is None:
            columns = self.columns
            record = columns.record(i)
            if self._decorate is not None:
                self._decorate(record, i)
            if not self._keep:
                return record
            rows[i] = record
            token = record.get("token")  # the record's own string as the key: one string per record, not two
            self.by_token[token if type(token) is str else columns.token(i)] = record
        return record

    def record_of(self, token: str) -> dict:
        """The record whose token is `token`; KeyError(token) when there is none."""
        record = self.by_token.get(token)
        if record is None:
            record = self.record(self.columns.index.find(token))
        return record

    def index_of(self, token: str) -> int:
        return self.columns.index.find(token)

    def __getitem__(self, item):
        if isinstance(item, slice):
            return [self.record(i) for i in range(*item.indices(self._length))]
        try:
            i = item.__index__()
        except (AttributeError, TypeError):
            raise TypeError(f"list indices must be integers or slices, not {type(item).__name__}") from None
        if i < 0:
            i += self._length
        if not 0 <= i < self._length:
            raise IndexError("list index out of range")
        return self.record(i)

    def __iter__(self):
        for i in range(self._length):
            yield self.record(i)

    def __eq__(self, other) -> bool:
        if isinstance(other, (list, tuple, Table)):
            return len(self) == len(other) and all(a == b for a, b in zip(self, other))
        return NotImplemented

    __hash__ = None

    def __add__(self, other) -> list:
        return list(self) + list(other)

    def __repr__(self) -> str:
        return f"<nuparquet.devkit table {self.name!r}: {self._length} records>"

    def _read_only(self, *args, **kwargs):
        raise ReadOnly(f"nusc.{self.name} is read-only: nuparquet.devkit.NuScenes serves the converted Parquet; "
                       f"copy it first (records = list(nusc.{self.name})) to change the list")

    __setitem__ = __delitem__ = __iadd__ = __imul__ = _read_only
    append = extend = insert = pop = remove = clear = sort = reverse = _read_only


def dataset_files(root: str, path: str) -> list[str]:
    """The Parquet files of a dataset directory, in name order (local outputs)."""
    return [str(p) for p in sorted(Path(root, path).rglob("*.parquet"))]


class ConvertedTables:
    """The source tables of one converted output: each one's files and the facts that rebuild its records.

    Args:
        root: the output directory (local).
        manifest: its manifest.json.
    """

    def __init__(self, root: str, manifest: dict):
        self.root = root
        self.manifest = manifest
        self._inferred = {f["dataset"].removeprefix("tables/"): f for f in manifest.get("files", ())
                          if f.get("kind") == "table_inferred"}

    def names(self) -> list[str]:
        """Every converted source table, in manifest order."""
        return [n.removeprefix("tables/") for n in self.manifest["datasets"] if n.startswith("tables/")]

    def rows(self, name: str) -> int:
        return int(self.manifest["datasets"][f"tables/{name}"]["rows"])

    def files(self, name: str) -> list[str]:
        entry = self.manifest["datasets"][f"tables/{name}"]
        files = dataset_files(self.root, entry.get("path", f"tables/{name}"))
        if not files:
            raise FormatError(f"{self.root}: tables/{name} is listed in manifest.json but has no Parquet file; "
                              "convert the dataroot again")
        return files

    def read(self, name: str, columns: list[str]) -> pa.Table:
        """Only `columns` of table `name` (the reverse indexes need a few columns of the large tables)."""
        return read_table(self.files(name), columns)

    def columns(self, name: str) -> Columns | RecordColumns:
        """Every column of table `name`, with what rebuilds its records."""
        table = read_table(self.files(name))
        if name in self._inferred:
            return RecordColumns(table, self._inferred[name])
        from nuparquet.schemas import table_schemas

        facts = self.manifest["tables"][name]
        schema = table_schemas().get(name)
        empty_list = {f.name for f in schema.fields if f.empty_list_is_null} if schema else set()
        return Columns(table, facts["key_order"], facts.get("layouts"), set(facts.get("json_fields", ())), empty_list)
