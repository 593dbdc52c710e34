"""The frame index of a scene render: which sample_data each output picture shows, so a frame on disk (a video frame,
DIR/00042.jpg) can be traced back.

One row per (output picture, tile): `frame` (the picture's number: video frame n, DIR/<n:05d>.jpg), `time_us` (the
output's time), `tile` (its place in the picture, row by row) and `channel`, the `sample_data_token` and `timestamp`
of the frame the plan matched to the tile (null: none), `drawn` (False where that frame's file was missing or
unreadable and a placeholder stands in), and `shows_frame`: the picture it shows, itself, or an earlier one repeated
when nothing new could be drawn (a missing image): every output keeps its place in time, so video frame n is at
n / fps however many images were missing. Written as `frames.parquet` in --frames-dir and `<video>.frames.parquet`
beside the video.
"""

from __future__ import annotations

import os
from pathlib import Path

import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq

from nuparquet.atomic import partial_path, remove_stale

INDEX_NAME = "frames.parquet"
SCHEMA = pa.schema([
    pa.field("frame", pa.int32(), nullable=False),
    pa.field("time_us", pa.int64(), nullable=False),
    pa.field("tile", pa.int16(), nullable=False),
    pa.field("channel", pa.large_string(), nullable=False),  # large: polars' own strings, written without a cast
    pa.field("sample_data_token", pa.large_string()),
    pa.field("timestamp", pa.int64()),
    pa.field("drawn", pa.bool_(), nullable=False),
    pa.field("shows_frame", pa.int32(), nullable=False),
])


def index_for_video(video: Path) -> Path:
    """`scene-0061.mp4` -> `scene-0061.frames.parquet`."""
    return Path(video).with_suffix(".frames.parquet")


def write_index(rows: list[dict], path: Path) -> Path:
    """The rows as Parquet at `path`, atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale(path)
    partial = partial_path(path)
    # Built by polars: pyarrow's builders from Python values (`from_pylist`, `pa.array`, `empty_table`) import pandas,
    # ~0.35 s, more than a 40-frame render's drawing and encoding.
    columns = pl.DataFrame(rows, schema=pl.Schema(SCHEMA)).to_arrow().columns
    table = pa.Table.from_arrays(columns, schema=SCHEMA)  # the same types: no cast (pyarrow.compute, ~0.1 s)
    pq.write_table(table, partial)
    os.replace(partial, path)
    return path
