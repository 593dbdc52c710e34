"""`sensor_files/camera/`, `sensor_files/lidar/`, `sensor_files/radar/`: the sensor files themselves, byte for
byte, keyframes and sweeps (`convert --embed camera,lidar,radar`, any subset), so that the output alone serves
images and points (`nuparquet.sensors.embedded` reads them back through `ds.sensors`).

The files are stored as they are rather than as decoded points: the test of an embedded file is that it is the file
(byte-identical), every reader keeps its one decoder of the file format (`sources.points`, cv2 for JPEGs), and the
decoded points already have their datasets (`--sensors`: `lidar_points/`, `radar_points/`, which the reader prefers
when a frame is there).

One part file per scene (`part-{i:05d}.parquet`, scenes in name order; manifest `scene_parts` maps a scene to its
file), rows in channel then time order. Memory: the files are read and written one row group at a time (whole
files, at most `ROW_GROUP_BYTES` (256 KiB) unless one file is larger), never a whole scene or modality.
"""

from __future__ import annotations

from functools import partial

import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq

from nuparquet.conversion.builder import BuildContext, Builder, WrittenParts
from nuparquet.conversion.builders.points import MAX_LISTED_MISSING, scenes_with_frames
from nuparquet.conversion.write import parquet_part_name
from nuparquet.problems import Problem, ProblemsFound
from nuparquet.schemas import dataset_schemas
from nuparquet.sensors.embedded import embedded_name
from nuparquet.sensors.reader import inside

# A row group closes before the file that would take it past this: reading one frame reads one group (pyarrow
# reads a column chunk whole), so a nuScenes camera image (~100-300 kB) or lidar file (~700 kB) is alone or
# nearly so in its group, radar files (~5 kB) ~50 to a group. 1 MiB groups made a single image's read ~5x slower
# than the file's (benchmarks/embedded_sensors.py); smaller ones only grow the footers (~0.5 kB per group).
ROW_GROUP_BYTES = 256 << 10
_DICTIONARY = ["scene_name", "channel"]


def schema() -> pa.Schema:
    return dataset_schemas()["sensor_files/<modality>"].arrow_schema()


def embed_frames(ctx: BuildContext, modality: str) -> pl.DataFrame:
    """Every sample_data row of `modality` (keyframes and sweeps) in output order."""
    return (ctx.dataset("frames").filter(pl.col("modality").cast(pl.String) == modality)
            .select(pl.col("token").alias("sample_data_token"), pl.col("scene_name").cast(pl.String),
                    pl.col("channel").cast(pl.String), "timestamp", "filename")
            .collect().sort("scene_name", "channel", "timestamp", "sample_data_token"))


def write_scene(path, rows: pl.DataFrame, dataroot) -> tuple[int, list[str]]:
    """The files of one scene's `rows` into the part file `path`: (rows written, filenames missing or outside the
    dataroot)."""
    written, missing, batch, batch_bytes = 0, [], [], 0
    arrow = schema()
    compression = {name: "zstd" for name in arrow.names} | {"bytes": "none"}
    with pq.ParquetWriter(path, arrow, compression=compression, use_dictionary=_DICTIONARY,
                          write_statistics=["scene_name", "channel", "timestamp"]) as writer:
        def flush() -> None:
            if batch:
                writer.write_table(pa.Table.from_pylist(batch, schema=arrow), row_group_size=len(batch))
        for row in rows.iter_rows(named=True):
            file = inside(dataroot, row["filename"])
            try:
                data = file.read_bytes() if file is not None else None
            except OSError:  # a missing file (a partial download: sweeps are a download of their own)
                data = None
            if data is None:
                missing.append(row["filename"])
                continue
            if batch and batch_bytes + len(data) > ROW_GROUP_BYTES:
                flush()
                batch, batch_bytes = [], 0
            batch.append({**row, "bytes": data})
            batch_bytes += len(data)
            written += 1
        flush()
    return written, missing


def build_embedded(ctx: BuildContext, modality: str) -> dict[str, WrittenParts]:
    name = embedded_name(modality)
    directory = ctx.out / name
    directory.mkdir(parents=True, exist_ok=True)
    frames = embed_frames(ctx, modality)
    no_scene = frames.filter(pl.col("scene_name").is_null()).height  # only --allow-dangling lets such rows through
    frames = frames.filter(pl.col("scene_name").is_not_null())
    rows_written, missing, scene_parts = 0, [], {}
    for part, ((scene,), rows) in enumerate(frames.partition_by("scene_name", as_dict=True,
                                                                maintain_order=True).items()):
        scene_parts[scene] = parquet_part_name(part)
        written, lost = write_scene(directory / scene_parts[scene], rows, ctx.dataroot)
        rows_written += written
        missing += lost
        if ctx.reporter:
            ctx.reporter.advance(step=f"{name} {scene}")
    if ctx.options.strict and missing:
        raise ProblemsFound([Problem(m, "sensor file missing (--strict)") for m in missing])
    if not scene_parts:  # no frames of this modality: an empty, scannable dataset
        pq.write_table(schema().empty_table(), directory / parquet_part_name(0))
    extra = {"frames": rows_written, "missing_count": len(missing), "missing_files": missing[:MAX_LISTED_MISSING],
             "scene_parts": scene_parts}
    if missing:
        ctx.warnings.append(f"{name}: {len(missing)} sensor file(s) missing, not embedded (listed in manifest.json "
                            f"datasets.{name}.missing_files; --strict makes this an error)")
    if no_scene:
        extra["no_scene_frames"] = no_scene
    size = sum(p.stat().st_size for p in directory.glob("*.parquet"))
    return {name: WrittenParts(schema(), rows_written, size, max(len(scene_parts), 1), extra)}


def _wanted(modality: str, ctx: BuildContext) -> str | None:
    return None if modality in ctx.options.embed else f"not requested (--embed {modality})"


def _units(modality: str, ctx: BuildContext) -> int:
    return scenes_with_frames(ctx, modality, keyframes_only=False)


def _builder(modality: str) -> Builder:
    return Builder(embedded_name(modality), partial(build_embedded, modality=modality), scope="whole",
                   schema="sensor_files/<modality>", wanted=partial(_wanted, modality), needs=("frames",),
                   units=partial(_units, modality))


CAMERA_BUILDER, LIDAR_BUILDER, RADAR_BUILDER = (_builder(m) for m in ("camera", "lidar", "radar"))
