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

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq

from nuparquet.errors import UsageError

LIDAR_ARRAY_COLUMNS = ("x", "y", "z", "intensity", "ring")
# Columns every points dataset has before its sensor fields (schemas/lidar_points.json, radar_points.json).
FRAME_COLUMNS = ("sample_data_token", "scene_name", "channel", "timestamp", "is_key_frame", "point_index")


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
    fields: tuple[str, ...]  # the dataset's columns

    @classmethod
    def read(cls, paths: list[str]) -> RowGroupIndex:
        rows: list[tuple] = []
        fields: tuple[str, ...] = ()
        for i, path in enumerate(paths):
            meta = pq.read_metadata(path)
            fields = tuple(meta.schema.to_arrow_schema().names)
            token_col, scene_col = fields.index("sample_data_token"), fields.index("scene_name")
            for g in range(meta.num_row_groups):
                group = meta.row_group(g)
                if group.num_rows == 0:
                    continue
                token, scene = group.column(token_col).statistics, group.column(scene_col).statistics
                rows.append((i, g, _text(token.min), _text(token.max), _text(scene.min), _text(scene.max)))
        columns = list(zip(*rows)) if rows else [[]] * 6
        return cls(paths, np.array(columns[0], dtype=np.int64), np.array(columns[1], dtype=np.int64),
                   *(np.array(c, dtype=str) for c in columns[2:]), fields)

    def groups_for_tokens(self, tokens: Sequence[str]) -> np.ndarray:
        """(G,) bool: row groups whose token range holds any of `tokens`."""
        wanted = np.zeros(self.file.size, dtype=bool)
        for token in set(tokens):
            wanted |= (self.token_min <= token) & (token <= self.token_max)
        return wanted

    def groups_for_scene(self, scene: str) -> np.ndarray:
        return (self.scene_min <= scene) & (scene <= self.scene_max)

    def read_groups(self, wanted: np.ndarray, columns: Sequence[str]) -> pa.Table:
        """The rows of the wanted row groups (files in order, groups in order)."""
        tables = []
        for i in np.unique(self.file[wanted]):
            groups = self.group[wanted & (self.file == i)].tolist()
            tables.append(pq.ParquetFile(self.paths[i]).read_row_groups(groups, columns=list(columns)))
        return pa.concat_tables(tables) if tables else None


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def select_points(index: RowGroupIndex, tokens: str | Sequence[str] | None = None, *, scene: str | None = None,
                  channel: str | None = None, columns: Sequence[str] | None = None) -> pl.DataFrame:
    """The points of the frames `tokens` (in the order given, each frame in file order) or of `scene` (optionally
    one `channel`; frames in dataset order), reading only the row groups that can hold them. `columns`: those
    columns (default all)."""
    if (tokens is None) == (scene is None):
        raise UsageError("give sample_data token(s) or scene=..., not both or neither")
    columns = list(columns) if columns is not None else list(index.fields)
    unknown = [c for c in columns if c not in index.fields]
    if unknown:
        raise UsageError(f"no column {', '.join(map(repr, unknown))} (columns: {', '.join(index.fields)})")
    read = list(dict.fromkeys([*columns, "sample_data_token", "scene_name", "channel", "point_index"]))
    if tokens is not None:
        token_list = [tokens] if isinstance(tokens, str) else list(tokens)
        table = index.read_groups(index.groups_for_tokens(token_list), read)
        frame = _frame(table, read).with_columns(pl.col("sample_data_token").cast(pl.String))
        order = pl.DataFrame({"sample_data_token": token_list, "_order": np.arange(len(token_list))})
        frame = frame.join(order, on="sample_data_token", how="inner").sort("_order", "point_index", maintain_order=True)
        found = set(frame["sample_data_token"].unique().to_list())
        missing = [t for t in token_list if t not in found]
        if missing:
            raise UsageError(f"no points for sample_data {', '.join(missing[:5])}"
                             f"{' ...' if len(missing) > 5 else ''} (not converted, or not a frame of this sensor type)")
    else:
        table = index.read_groups(index.groups_for_scene(scene), read)
        frame = _frame(table, read).filter(pl.col("scene_name").cast(pl.String) == scene)
        if channel is not None:
            frame = frame.filter(pl.col("channel").cast(pl.String) == channel)
    return frame.select(columns)


def _frame(table: pa.Table | None, columns: list[str]) -> pl.DataFrame:
    if table is None:
        return pl.DataFrame({c: [] for c in columns}).with_columns(pl.all().cast(pl.String))
    return pl.from_arrow(table)


def lidar_array(frame: pl.DataFrame) -> np.ndarray:
    """(N, 5) float32 [x, y, z, intensity, ring] from lidar_points rows (ring NaN where the files had none)."""
    out = np.empty((frame.height, len(LIDAR_ARRAY_COLUMNS)), dtype=np.float32)
    for j, name in enumerate(LIDAR_ARRAY_COLUMNS):
        out[:, j] = frame[name].cast(pl.Float32).fill_null(np.nan).to_numpy() if frame.height else []
    return out


def radar_fields(index: RowGroupIndex) -> list[str]:
    """The PCD fields of a radar_points dataset, in header order."""
    return [f for f in index.fields if f not in FRAME_COLUMNS and f != "passes_default_filters"]


def radar_array(frame: pl.DataFrame, fields: list[str]) -> np.ndarray:
    """(N, F) float64 of the PCD fields (the devkit's `RadarPointCloud.points` is this transposed)."""
    out = np.empty((frame.height, len(fields)), dtype=np.float64)
    for j, name in enumerate(fields):
        out[:, j] = frame[name].cast(pl.Float64).to_numpy() if frame.height else []
    return out
