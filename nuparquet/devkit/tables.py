"""The converted source tables (`tables/<name>`) as the devkit's lists of dicts, each record built when first asked for.

The devkit `json.load`s every table at start-up and keeps a dict per record. Here a table's Parquet files are read
on first use into Arrow buffers (no Python object per value: `nuparquet.devkit.columns`), and a record is built from them when it is
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

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from nuparquet.devkit.columns import Columns, RecordColumns, nested, read_table
from nuparquet.devkit.errors import ReadOnly
from nuparquet.errors import FormatError

if TYPE_CHECKING:
    import pyarrow as pa


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


class ConvertedTables:
    """The source tables of one converted output (a `Dataset`, local or in an object store): each one's files and
    the facts that rebuild its records."""

    def __init__(self, dataset):
        self.dataset = dataset
        self.root = dataset.root
        self.manifest = dataset.manifest
        self._filesystem = dataset.filesystem[0] if dataset.is_remote else None
        self._inferred = {f["dataset"].removeprefix("tables/"): f for f in self.manifest.get("files", ())
                          if f.get("kind") == "table_inferred"}

    def names(self) -> list[str]:
        """Every converted source table, in manifest order."""
        return [n.removeprefix("tables/") for n in self.manifest["datasets"] if n.startswith("tables/")]

    def rows(self, name: str) -> int:
        return int(self.manifest["datasets"][f"tables/{name}"]["rows"])

    def files(self, name: str) -> list[str]:
        files = [path for path, _ in self.dataset.files(f"tables/{name}")]
        if not files:
            raise FormatError(f"{self.root}: tables/{name} is listed in manifest.json but has no Parquet file; "
                              "convert the dataroot again")
        return files

    def read(self, name: str, columns: list[str]) -> pa.Table:
        """Only `columns` of table `name` (the reverse indexes need a few columns of the large tables)."""
        return read_table(self.files(name), columns, self._filesystem)

    def columns(self, name: str) -> Columns | RecordColumns:
        """Every column of table `name`, with what rebuilds its records."""
        table = read_table(self.files(name), filesystem=self._filesystem)
        if name in self._inferred:
            return RecordColumns(table, self._inferred[name])
        from nuparquet.schemas import table_schemas

        facts = self.manifest["tables"][name]
        schema = table_schemas().get(name)
        empty_list = {f.name for f in schema.fields if f.empty_list_is_null} if schema else set()
        for field in schema.fields if schema else ():
            if field.json_shape and field.name in table.column_names:  # flat in the column, nested in the JSON
                i = table.column_names.index(field.name)
                table = table.set_column(i, field.name, nested(table.column(i), field.json_shape))
        return Columns(table, facts["key_order"], facts.get("layouts"), set(facts.get("json_fields", ())), empty_list)
