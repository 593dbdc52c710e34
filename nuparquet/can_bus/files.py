"""The CAN bus expansion files of a conversion as `json.load` gave them, rebuilt from `can_bus/<message>/`,
`can_bus/meta/` and `can_bus/route/` with the facts the manifest keeps for each file (`files[]`: its first record's
key order, records in another order, integers among floats, fields held as JSON text). What `export-json` writes
back and what `nuparquet.devkit.can_bus.can_bus_api.NuScenesCanBus.get_messages` returns; nothing here reads the
JSON files.

A file is one scene's rows of one dataset. The converter starts a row group at each scene, so the rows are found by
the row groups' `scene_name` statistics and one file costs one row group's read (a group holding several scenes is
filtered). Each call builds new Python objects: callers may change what they get (BEVFormer's converter pops keys).
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import PurePosixPath

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from nuparquet.columns import to_numpy
from nuparquet.sources.json_records import records_from_columns

MESSAGES, META, ROUTE = "can_bus_messages", "can_bus_meta", "can_bus_route"  # the manifest's file kinds
KINDS = (MESSAGES, META, ROUTE)


class CanBusFiles:
    """The converted CAN bus files of an output (a `Dataset`, local or in an object store), by file name
    (``scene-0061_pose.json``)."""

    def __init__(self, dataset):
        self.dataset = dataset
        self.root = dataset.root
        self._manifest = dataset.manifest
        self._entries: dict[str, dict] | None = None
        self._rows: dict[str, SceneRows] = {}

    @property
    def entries(self) -> dict[str, dict]:
        """{file name: its manifest entry}, in the manifest's order (by message type, then scene)."""
        if self._entries is None:
            self._entries = {PurePosixPath(e["path"]).name: e for e in self._manifest.get("files", [])
                             if e.get("kind") in KINDS}
        return self._entries

    def content(self, name: str) -> list | dict:
        """File `name` as `json.load` gave it: a list of messages, the meta object, or the route's [x, y] points.

        Raises:
            KeyError: no such file was converted.
        """
        return self.entry_content(self.entries[name])

    def entry_content(self, entry: dict) -> list | dict:
        """The file of manifest entry `entry` (one of `files[]`, of a CAN bus kind), as `content`."""
        kind = entry["kind"]
        keys = list(entry.get("keys", []))
        table = self._table(entry, keys + {META: ["message"]}.get(kind, []))
        with _collector_paused():
            columns = {k: python_values(table.column(k)) for k in keys}
            records = records_from_columns(columns, table.num_rows, keys, entry.get("json_fields", []),
                                           entry.get("int_values", {}), entry.get("key_orders", {}))
            if kind == META:
                return dict(zip(table.column("message").to_pylist(), records))
            if kind == ROUTE:
                return [[r["x"], r["y"]] for r in records]
            return records

    def table(self, name: str, columns: list[str]) -> pa.Table:
        """The rows of file `name` as Arrow (`columns` of its dataset), in the file's order: for callers that want
        numbers, not Python objects (KeyError: not converted)."""
        return self._table(self.entries[name], columns)

    def _table(self, entry: dict, columns: list[str]) -> pa.Table:
        if entry["kind"] != ROUTE:
            return self._scene_rows(entry["dataset"]).table(entry["scene"], columns)
        table = self._scene_rows(entry["dataset"]).table(entry["scene"], columns + ["point_index"])
        return table.take(pc.sort_indices(table.column("point_index")))

    def _scene_rows(self, dataset: str) -> SceneRows:
        if dataset not in self._rows:
            filesystem = self.dataset.filesystem[0] if self.dataset.is_remote else None
            self._rows[dataset] = SceneRows([path for path, _ in self.dataset.files(dataset)], filesystem)
        return self._rows[dataset]

    def __getstate__(self) -> dict:  # open Parquet files stay behind; a copy opens its own
        return {**self.__dict__, "_rows": {}}


class SceneRows:
    """One dataset's Parquet files and which of their row groups may hold each scene (by statistics)."""

    def __init__(self, paths: list[str], filesystem=None):
        self.files = [pq.ParquetFile(path, filesystem=filesystem) for path in paths]
        self.names = [set(parquet.schema_arrow.names) for parquet in self.files]
        self.groups: list[tuple[int, int, str | None, str | None]] = []  # file, row group, min and max scene
        for f, parquet in enumerate(self.files):
            column = parquet.schema_arrow.get_field_index("scene_name")
            for g in range(parquet.metadata.num_row_groups):
                stats = parquet.metadata.row_group(g).column(column).statistics
                bounds = (stats.min, stats.max) if stats is not None and stats.has_min_max else (None, None)
                self.groups.append((f, g, *bounds))

    def table(self, scene: str, columns: list[str]) -> pa.Table:
        """The rows of `scene` (columns `columns`), in file order."""
        parts, exact = [], True
        for f, g, low, high in self.groups:
            if low is None or low <= scene <= high:
                names = [c for c in columns if c in self.names[f]]
                parts.append(self.files[f].read_row_group(g, columns=names + ["scene_name"], use_threads=False))
                exact &= low == high == scene
        if not parts:
            return pa.table({c: pa.array([], pa.null()) for c in columns + ["scene_name"]})
        table = parts[0] if len(parts) == 1 else pa.concat_tables(parts)
        if not exact:
            table = table.filter(pc.equal(table.column("scene_name"), scene))
        return table


def python_values(column: pa.ChunkedArray) -> list:
    """The column's values as Python objects, as `to_pylist` gives them; numbers and fixed-size lists of numbers
    through numpy (`tolist`), several times faster."""
    kind = column.type
    if column.null_count == 0 and len(column):
        if pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_boolean(kind):
            return column.to_numpy().tolist()
        inner = kind.value_type if pa.types.is_fixed_size_list(kind) else None
        if inner is not None and (pa.types.is_integer(inner) or pa.types.is_floating(inner)):
            flat = pc.list_flatten(column)
            if flat.null_count == 0:
                dtype = np.int64 if pa.types.is_integer(inner) else np.float64
                return to_numpy(column, (kind.list_size,), dtype).tolist()
    return column.to_pylist()


@contextmanager
def _collector_paused() -> Iterator[None]:
    """Python's cycle collector off while a file's objects are built: they hold no cycles, and the collections that
    tens of thousands of new lists and dicts set off (each walking every object built so far) cost more than building
    them. Restored as it was."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
