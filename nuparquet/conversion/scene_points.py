"""One scene's sensor points as one Parquet part file: the picklable per-scene task of the `lidar_points/` and
`radar_points/` conversion (`nuparquet.conversion.builders.points` makes the tasks and runs them).

Kept out of `nuparquet.conversion` so that a worker process imports only numpy, pyarrow and the point readers
(~0.5 s instead of ~1.5 s with DuckDB and polars). `convert_scene(task) -> SceneSummary` is a top-level function
of explicit inputs: any engine (a process pool, Ray) can run it.

Memory: a task holds one row group at a time — whole frames, at most `ROW_GROUP_ROWS` points unless one frame
is larger (a nuScenes lidar frame: ~35k points, ~1.5 MB of columns) — plus the file being read.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from nuparquet.problems import Problem
from nuparquet.schemas import dataset_schemas
from nuparquet.sources import points as source

# Points per row group: whole frames, a new group when the next frame would pass this. Radar frames (~125
# points) share groups; a lidar frame (~35k) gets its own, so reading one frame reads one group.
ROW_GROUP_ROWS = 32768
LABELS = (("lidarseg", "lidarseg_label", source.read_lidarseg_bin), ("panoptic", "panoptic_label", source.read_panoptic_npz))
_DICTIONARY_COLUMNS = ["sample_data_token", "scene_name", "channel"]
# Statistics where they prune (frame lookups, scene/time filters); per-frame min/max of x, y, z span the whole
# cloud and would cost ~10% of the write for nothing.
_STATISTICS_COLUMNS = [*_DICTIONARY_COLUMNS, "timestamp", "is_key_frame", "point_index"]
# LZ4 (raw): on nuScenes lidar ~40% faster to write and ~2x faster to read than zstd, ~15% larger (measured on
# the extract: 13.9 vs 12.1 MB per 1.4M points; the .pcd.bin files are 27.8 MB).
COMPRESSION = "lz4"
WRITE_BATCH_ROWS = 65536  # values encoded per batch (pyarrow's default 1024): ~15% less CPU per write


@dataclass(frozen=True)
class SceneTask:
    """One scene's sensor files of one modality: everything `convert_scene` needs, picklable."""

    dataroot: str
    path: str  # the part file to write (under the temporary output)
    part: int
    scene_name: str
    modality: str  # "lidar" or "radar"
    frames: dict[str, list]  # columns token, channel, timestamp, is_key_frame, filename, lidarseg, panoptic (None: no file)
    lidar_columns: int = source.NUSCENES_LIDAR_COLUMNS


@dataclass
class SceneSummary:
    part: int
    rows: int = 0
    bytes: int = 0
    written: bool = False
    missing: list[str] = field(default_factory=list)  # sensor files (relative to the dataroot) not found
    problems: list[Problem] = field(default_factory=list)
    pcd_layout: tuple[tuple[str, str], ...] | None = None  # radar: (field, numpy type) of the header
    pcd_file: str | None = None  # the radar file the layout was read from
    labelled: dict[str, int] = field(default_factory=dict)  # frames with a lidarseg / panoptic label file

    def to_json(self) -> dict:
        """A JSON-able form (the engine keeps a finished scene's value in a marker file)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, value: dict) -> SceneSummary:
        layout = value.get("pcd_layout")
        return cls(**{**value, "problems": [Problem(**p) for p in value.get("problems", [])],
                      "pcd_layout": None if layout is None else tuple(tuple(pair) for pair in layout)})


def convert_unit(unit, part: Path) -> dict:
    """The scale-out engine's task (`nuparquet.engine`): the scene `unit.args` (a SceneTask) into the part folder
    `part`, as `points.parquet`; its summary as JSON. Here, not in the builder, so a worker imports only this."""
    return convert_scene(dataclasses.replace(unit.args, path=str(Path(part) / "points.parquet"))).to_json()


def convert_scene(task: SceneTask) -> SceneSummary:
    """Read the scene's files in order and write the part file `task.path`."""
    summary = SceneSummary(task.part)
    root = Path(task.dataroot)
    path = Path(task.path)
    writer: pq.ParquetWriter | None = None
    group: list[dict] = []
    group_rows = 0

    def flush() -> None:
        nonlocal writer, group, group_rows
        if not group:
            return
        table = _lidar_table(group) if task.modality == "lidar" else _radar_table(group)
        if writer is None:
            writer = pq.ParquetWriter(path, table.schema, compression=COMPRESSION, write_statistics=_STATISTICS_COLUMNS,
                                      use_dictionary=_DICTIONARY_COLUMNS, column_encoding=_encodings(table.schema),
                                      write_batch_size=WRITE_BATCH_ROWS)
        writer.write_table(table, row_group_size=max(table.num_rows, 1))
        summary.rows += table.num_rows
        group, group_rows = [], 0

    frames = task.frames
    for i, filename in enumerate(frames["filename"]):
        frame = {key: frames[key][i] for key in ("token", "channel", "timestamp", "is_key_frame")}
        frame["scene_name"] = task.scene_name
        try:
            if task.modality == "lidar" and source.is_pcd(filename):  # TruckScenes: a PCD, its fields by name
                frame["points"] = source.read_lidar_pcd(root / filename)
                frame["labels"] = {}
                _same_layout(summary, frame["points"], root, filename)
            elif task.modality == "lidar":
                frame["points"] = _read_lidar(root, filename, task.lidar_columns)
                labels = {}
                for table, column, reader in LABELS:
                    if frames[table][i] is not None:
                        labels[column] = _read_labels(root, frames[table][i], filename, len(frame["points"]), reader, table)
                frame["labels"] = labels
                for table, column, _reader in LABELS:
                    summary.labelled[table] = summary.labelled.get(table, 0) + (column in labels)
            else:
                frame["points"] = source.read_radar_pcd(root / filename)
                _same_layout(summary, frame["points"], root, filename)
        except FileNotFoundError:
            summary.missing.append(filename)
            continue
        except source.PointFileError as exc:
            summary.problems.append(Problem(_relative(exc.path, root), exc.reason, token=frame["token"]))
            continue
        n = len(frame["points"])
        if group and group_rows + n > ROW_GROUP_ROWS:
            flush()
        group.append(frame)
        group_rows += n
    flush()
    if writer is not None:
        writer.close()
        summary.written = True
        summary.bytes = path.stat().st_size
    return summary


def _same_layout(summary: SceneSummary, points: np.ndarray, root: Path, filename: str) -> None:
    """Every PCD of a scene has the first one's fields (one dataset, one schema)."""
    layout = tuple((n, points.dtype[n].str) for n in points.dtype.names)
    if summary.pcd_layout is None:
        summary.pcd_layout, summary.pcd_file = layout, filename
    elif layout != summary.pcd_layout:
        raise source.PointFileError(root / filename, f"PCD fields {layout_text(layout)} differ from "
                                    f"{summary.pcd_file}'s {layout_text(summary.pcd_layout)}")


def _encodings(schema: pa.Schema) -> dict[str, str]:
    """BYTE_STREAM_SPLIT for float columns (the codec then packs lidar floats ~20% smaller, and they decode
    faster) and DELTA_BINARY_PACKED for `point_index` (0, 1, 2, ...: 3 MB per 1.4M points plain, ~0 delta)."""
    encodings = {f.name: "BYTE_STREAM_SPLIT" for f in schema if pa.types.is_floating(f.type)}
    return encodings | {"point_index": "DELTA_BINARY_PACKED"}


def _read_lidar(root: Path, filename: str, columns: int) -> np.ndarray:
    points = source.read_lidar_bin(root / filename, columns)
    if columns >= 5:
        ring = points[:, 4]
        if not np.array_equal(ring.astype(np.uint8).astype(np.float32), ring):
            bad = int(np.flatnonzero(ring.astype(np.uint8).astype(np.float32) != ring)[0])
            raise source.PointFileError(root / filename, f"point {bad}: 5th value {ring[bad]!r} is not a ring index "
                                        "(an integer 0..255); pass --lidar-columns if the files hold other values")
    return points


def _read_labels(root: Path, label_file: str, sensor_file: str, n_points: int, reader, table: str) -> np.ndarray:
    try:
        labels = reader(root / label_file)
    except FileNotFoundError:
        raise source.PointFileError(root / label_file, f"label file missing ({table}.json names it for "
                                    f"{sensor_file})") from None
    if len(labels) != n_points:
        raise source.PointFileError(root / label_file, f"{len(labels)} labels but {sensor_file} has {n_points} points")
    return labels


def _relative(path: str, root: Path) -> str:
    try:
        return str(Path(path).relative_to(root))
    except ValueError:
        return str(path)


def layout_text(layout) -> str:
    return " ".join(f"{name}:{kind}" for name, kind in layout)


def _frame_columns(group: list[dict]) -> tuple[dict[str, pa.Array], np.ndarray]:
    """The per-frame columns repeated over each frame's points (dictionary-encoded), and (F,) point counts."""
    counts = np.array([len(f["points"]) for f in group], dtype=np.int64)
    n = int(counts.sum())
    # A group of one frame (every nuScenes lidar frame) needs no per-point gather: all indices 0.
    frame_of_point = np.zeros(n, np.int32) if len(group) == 1 else np.repeat(np.arange(len(group), dtype=np.int32), counts)
    columns = {}
    for name, key in (("sample_data_token", "token"), ("scene_name", "scene_name"), ("channel", "channel")):
        values = [f[key] for f in group]
        unique = sorted(set(values))
        if values == unique:  # distinct and in order (one frame; tokens of a group in order): code = frame
            indices = frame_of_point
        else:
            indices = np.array([unique.index(v) for v in values], dtype=np.int32)[frame_of_point]
        columns[name] = pa.DictionaryArray.from_arrays(pa.array(indices), pa.array(unique, pa.string()))
    per_frame = [(f["timestamp"], f["is_key_frame"]) for f in group]
    if len(group) == 1:
        columns["timestamp"] = pa.array(np.full(n, per_frame[0][0], dtype=np.int64))
        columns["is_key_frame"] = pa.array(np.full(n, per_frame[0][1], dtype=bool))
        columns["point_index"] = pa.array(np.arange(n, dtype=np.uint32))
        return columns, counts
    columns["timestamp"] = pa.array(np.repeat(np.array([p[0] for p in per_frame], dtype=np.int64), counts))
    columns["is_key_frame"] = pa.array(np.repeat(np.array([p[1] for p in per_frame], dtype=bool), counts))
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    columns["point_index"] = pa.array((np.arange(n, dtype=np.int64) - starts).astype(np.uint32))
    return columns, counts


def _lidar_table(group: list[dict]) -> pa.Table:
    columns, counts = _frame_columns(group)
    points = np.concatenate([f["points"] for f in group])
    layout = None
    if points.dtype.names:  # a lidar PCD: x, y, z, intensity by name, no ring, its other fields after the labels
        for name in source.LIDAR_PCD_FIELDS:
            columns[name] = pa.array(np.ascontiguousarray(points[name]))
        columns["ring"] = pa.nulls(len(points), pa.uint8())
        layout = tuple((n, points.dtype[n].str) for n in points.dtype.names)
    else:
        for j, name in enumerate(source.LIDAR_FIELDS[:4]):
            columns[name] = pa.array(points[:, j])
        columns["ring"] = (pa.array(points[:, 4].astype(np.uint8)) if points.shape[1] >= 5
                           else pa.nulls(len(points), pa.uint8()))
    for _table, column, _reader in LABELS:
        dtype = np.uint8 if column == "lidarseg_label" else np.uint16
        if not any(column in f["labels"] for f in group):  # sweeps, unlabelled datasets: all null, nothing to build
            columns[column] = pa.nulls(len(points), pa.from_numpy_dtype(dtype))
            continue
        has = np.repeat(np.array([column in f["labels"] for f in group]), counts)
        values = np.concatenate([f["labels"].get(column, np.zeros(len(f["points"]), dtype)) for f in group]).astype(dtype)
        columns[column] = pa.array(values, mask=~has) if not has.all() else pa.array(values)
    for name in (points.dtype.names or ()):
        if name not in source.LIDAR_PCD_FIELDS:
            columns[source.pcd_column(name)] = pa.array(np.ascontiguousarray(points[name]))
    return pa.table(columns, schema=lidar_schema(layout))


def _radar_table(group: list[dict]) -> pa.Table:
    columns, _counts = _frame_columns(group)
    points = np.concatenate([f["points"] for f in group])
    for name in points.dtype.names:
        columns[name] = pa.array(np.ascontiguousarray(points[name]))
    masks = [source.passes_default_filters(f["points"]) for f in group]
    columns["passes_default_filters"] = (pa.nulls(len(points), pa.bool_()) if masks[0] is None
                                         else pa.array(np.concatenate(masks)))
    return pa.table(columns, schema=radar_schema(tuple((n, points.dtype[n].str) for n in points.dtype.names)))


@functools.cache
def lidar_schema(layout: tuple[tuple[str, str], ...] | None = None) -> pa.Schema:
    """schemas/lidar_points.json; for lidar PCD files (`layout`: their fields and numpy types), then the fields
    beyond x, y, z, intensity in header order (`sources.points.pcd_column` names)."""
    fixed = dataset_schemas()["lidar_points"].arrow_schema()
    more = [pa.field(source.pcd_column(name), pa.from_numpy_dtype(np.dtype(kind)), nullable=False)
            for name, kind in layout or () if name not in source.LIDAR_PCD_FIELDS]
    return pa.schema(list(fixed) + more, metadata=fixed.metadata)


@functools.cache
def radar_schema(layout: tuple[tuple[str, str], ...] | None) -> pa.Schema:
    """The fixed columns of schemas/radar_points.json, the PCD fields in header order, `passes_default_filters`."""
    fixed = dataset_schemas()["radar_points"].arrow_schema()
    last = fixed.field("passes_default_filters")
    head = [f for f in fixed if f.name != last.name]
    pcd = [pa.field(name, pa.from_numpy_dtype(np.dtype(kind)), nullable=False) for name, kind in layout or ()]
    return pa.schema(head + pcd + [last], metadata=fixed.metadata)
