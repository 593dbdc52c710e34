"""Points of chosen frames from `lidar_points/` and `radar_points/`, reading only the row groups that hold them.

The converter writes whole frames per row group (a nuScenes lidar frame alone in its group), so the Parquet
footers' min/max of `sample_data_token` and `scene_name` say which row groups can hold a frame. `RowGroupIndex`
collects them once per dataset (footers only); a lookup reads just the candidate row groups.

```python
ds = nuparquet.open("OUT")
xyzir = ds.points(token)                      # (N, 5) float32 x, y, z, intensity, ring (lidar frame, as stored)
xyzir = ds.points([t1, t2])                   # frames in the order given, each in file order
df = ds.points(scene="scene-0061", columns=["x", "y", "z", "lidarseg_label"])   # a polars DataFrame
radar = ds.radar_points(token)                # (N, F) float64, the PCD fields as devkit RadarPointCloud (F, N).T
```
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from nuparquet.errors import UsageError
from nuparquet.sources.points import LIDAR_FIELDS

# Columns every points dataset has before its sensor fields (schemas/lidar_points.json, radar_points.json).
FRAME_COLUMNS = ("sample_data_token", "scene_name", "channel", "timestamp", "is_key_frame", "point_index")


class FramesNotConverted(UsageError):
    """Frames asked for that the points dataset does not hold (not converted, a sweep left out, a file missing at
    conversion, or not a frame of this sensor type); `tokens` are they."""

    def __init__(self, tokens: Sequence[str]):
        self.tokens = list(tokens)
        super().__init__(f"no points for sample_data {', '.join(self.tokens[:5])}"
                         f"{' ...' if len(self.tokens) > 5 else ''} (not converted, or not a frame of this sensor type)")


@dataclass(frozen=True)
class RowGroupIndex:
    """Per row group of a points dataset (footers only): its file and the min/max of token and scene."""

    paths: list[str]
    file: np.ndarray  # (G,) index into paths
    group: np.ndarray  # (G,) row group within its file
    token_min: np.ndarray  # (G,) str
    token_max: np.ndarray
    scene_min: np.ndarray
    scene_max: np.ndarray
    schema: pa.Schema  # the dataset's columns
    filesystem: object = None  # the pyarrow FileSystem of an object-store dataset (None: local paths)
    _files: dict = field(default_factory=dict, compare=False, repr=False)  # open pq.ParquetFile by path
    # One reader at a time: a pq.ParquetFile is not safe to read from two threads (the renderer's decode threads
    # read lidar points concurrently: pyarrow's ReadRangeCache raised, or the process crashed).
    _lock: threading.Lock = field(default_factory=threading.Lock, compare=False, repr=False)

    @classmethod
    def read(cls, paths: list[str], filesystem=None) -> RowGroupIndex:
        """The footers of `paths` (local, or inside the pyarrow `filesystem` of an object store)."""
        rows: list[tuple] = []
        schema = pa.schema([])
        for i, path in enumerate(paths):
            meta = pq.read_metadata(path, filesystem=filesystem)
            schema = meta.schema.to_arrow_schema()
            fields = schema.names
            token_col, scene_col = fields.index("sample_data_token"), fields.index("scene_name")
            for g in range(meta.num_row_groups):
                group = meta.row_group(g)
                if group.num_rows == 0:
                    continue
                token, scene = group.column(token_col).statistics, group.column(scene_col).statistics
                rows.append((i, g, _text(token.min), _text(token.max), _text(scene.min), _text(scene.max)))
        columns = list(zip(*rows)) if rows else [[]] * 6
        return cls(paths, np.array(columns[0], dtype=np.int64), np.array(columns[1], dtype=np.int64),
                   *(np.array(c, dtype=str) for c in columns[2:]), schema, filesystem=filesystem)

    @property
    def fields(self) -> tuple[str, ...]:
        return tuple(self.schema.names)

    def groups_for_tokens(self, tokens: Sequence[str]) -> np.ndarray:
        """(G,) bool: row groups whose token range holds any of `tokens`."""
        wanted = np.zeros(self.file.size, dtype=bool)
        for token in set(tokens):
            wanted |= (self.token_min <= token) & (token <= self.token_max)
        return wanted

    def groups_for_scene(self, scene: str) -> np.ndarray:
        return (self.scene_min <= scene) & (scene <= self.scene_max)

    def _parquet(self, g: int) -> pq.ParquetFile:
        """The open file of row group `g` (opened once: its footer is parsed once)."""
        path = self.paths[int(self.file[g])]
        if path not in self._files:
            self._files[path] = pq.ParquetFile(path, filesystem=self.filesystem)
        return self._files[path]

    def read_group(self, g: int, columns: Sequence[str]) -> pa.Table:
        """Row group `g` (an index into this table of groups)."""
        with self._lock:
            return self._parquet(g).read_row_group(int(self.group[g]), columns=list(columns))

    def read_groups(self, wanted: np.ndarray, columns: Sequence[str]) -> pa.Table | None:
        """The rows of the wanted row groups (files in order, groups in order)."""
        tables = [self.read_group(g, columns) for g in np.flatnonzero(wanted)]
        return pa.concat_tables(tables) if tables else None

    def read_frames(self, tokens: Sequence[str], columns: Sequence[str]) -> pa.Table:
        """The rows of frames `tokens`, in that order (each frame's rows as stored). A row group that holds one
        frame only (min token = max token: every nuScenes lidar frame) is taken whole, without a filter."""
        candidates = [np.flatnonzero((self.token_min <= t) & (t <= self.token_max)) for t in tokens]
        single = [c[0] for c, t in zip(candidates, tokens)
                  if len(c) == 1 and self.token_min[c[0]] == self.token_max[c[0]] == t]
        if len(single) == len(tokens):  # every frame alone in its row group (nuScenes lidar): one read per file run
            return self._read_whole_groups(np.array(single, dtype=np.int64), columns)
        read = list(dict.fromkeys([*columns, "sample_data_token"]))
        groups: dict[int, pa.Table] = {}
        pieces, missing = [], []
        for token, token_groups in zip(tokens, candidates):
            found = False
            for g in token_groups.tolist():
                if g not in groups:
                    groups[g] = self.read_group(g, read)
                table = groups[g]
                if self.token_min[g] != self.token_max[g]:
                    table = table.filter(_token_mask(table.column("sample_data_token"), token))
                if table.num_rows:
                    pieces.append(table.select(list(columns)))
                    found = True
            if not found:
                missing.append(token)
        if missing:
            raise FramesNotConverted(missing)
        return pa.concat_tables(pieces)


    def _read_whole_groups(self, groups: np.ndarray, columns: Sequence[str]) -> pa.Table:
        """Row groups `groups` (indices into this table, in the order wanted), one read per run of one file."""
        tables, start = [], 0
        while start < len(groups):
            stop = start
            while stop < len(groups) and self.file[groups[stop]] == self.file[groups[start]]:
                stop += 1
            with self._lock:
                tables.append(self._parquet(groups[start]).read_row_groups(self.group[groups[start:stop]].tolist(),
                                                                            columns=list(columns)))
            start = stop
        if not tables:  # no frame asked (`ds.points([])`): no rows, typed as the files (Arrow concatenates no tables)
            return pa.table({c: pa.array([], self.schema.field(c).type) for c in columns})
        return pa.concat_tables(tables)


def _token_mask(column: pa.ChunkedArray, token: str) -> pa.ChunkedArray:
    """Rows of a (dictionary-encoded) token column equal to `token`, compared on the dictionary indices."""
    masks = []
    for chunk in column.chunks:
        if pa.types.is_dictionary(chunk.type):
            position = chunk.dictionary.index(token).as_py()
            masks.append(pc.equal(chunk.indices, position) if position >= 0 else pa.array(np.zeros(len(chunk), bool)))
        else:
            masks.append(pc.equal(chunk, token))
    return pa.chunked_array(masks, pa.bool_())


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def select_points(index: RowGroupIndex, tokens: str | Sequence[str] | None = None, *, scene: str | None = None,
                  channel: str | None = None, columns: Sequence[str] | None = None) -> pa.Table:
    """The points of the frames `tokens` (in the order given, each frame in file order) or of `scene` (optionally
    one `channel`; frames in dataset order), reading only the row groups that can hold them, as an Arrow table
    of `columns` (default all)."""
    if (tokens is None) == (scene is None):
        raise UsageError("give sample_data token(s) or scene=..., not both or neither")
    columns = list(columns) if columns is not None else list(index.fields)
    unknown = [c for c in columns if c not in index.fields]
    if unknown:
        raise UsageError(f"no column {', '.join(map(repr, unknown))} (columns: {', '.join(index.fields)})")
    if tokens is not None:
        return index.read_frames([tokens] if isinstance(tokens, str) else list(tokens), columns)
    read = list(dict.fromkeys([*columns, "scene_name", "channel"]))
    table = index.read_groups(index.groups_for_scene(scene), read)
    if table is None:
        return pa.table({c: pa.array([], index.schema.field(c).type) for c in columns})
    keep = pc.equal(table.column("scene_name").cast(pa.string()), scene)
    if channel is not None:
        keep = pc.and_(keep, pc.equal(table.column("channel").cast(pa.string()), channel))
    return table.filter(keep).select(columns)


def lidar_array(table: pa.Table) -> np.ndarray:
    """(N, 5) float32 [x, y, z, intensity, ring] from lidar_points rows (ring NaN where the files had none).

    Column-major (each column contiguous, the devkit's (4, N) `points` layout transposed): the columns are copied
    whole instead of strided into rows, twice as fast; `np.ascontiguousarray` gives the row-major copy."""
    out = np.empty((len(LIDAR_FIELDS), table.num_rows), dtype=np.float32)
    for j, name in enumerate(LIDAR_FIELDS):
        column = table.column(name)
        if column.null_count:
            column = column.cast(pa.float32()).fill_null(np.nan)
        offset = 0
        for chunk in column.chunks:  # one chunk per frame: written in place, no combined temporary
            out[j, offset:offset + len(chunk)] = chunk.to_numpy(zero_copy_only=False)
            offset += len(chunk)
    return out.T


def radar_fields(index: RowGroupIndex) -> list[str]:
    """The PCD fields of a radar_points dataset, in header order."""
    return [f for f in index.fields if f not in FRAME_COLUMNS and f != "passes_default_filters"]


def radar_array(table: pa.Table, fields: list[str]) -> np.ndarray:
    """(N, F) float64 of the PCD fields (the devkit's `RadarPointCloud.points` is this transposed)."""
    out = np.empty((table.num_rows, len(fields)), dtype=np.float64)
    for j, name in enumerate(fields):
        out[:, j] = table.column(name).to_numpy()
    return out
