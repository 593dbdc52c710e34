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

from pathlib import Path

import polars as pl

from nuparquet.atomic import atomic_file

INDEX_NAME = "frames.parquet"
# Only `sample_data_token` and `timestamp` are ever null (no frame matched the tile).
SCHEMA = pl.Schema({
    "frame": pl.Int32, "time_us": pl.Int64, "tile": pl.Int16, "channel": pl.String, "sample_data_token": pl.String,
    "timestamp": pl.Int64, "drawn": pl.Boolean, "shows_frame": pl.Int32,
})


def index_for_video(video: Path) -> Path:
    """`scene-0061.mp4` -> `scene-0061.frames.parquet`."""
    return Path(video).with_suffix(".frames.parquet")


def write_index(rows: list[dict], path: Path) -> Path:
    """The rows as Parquet at `path`, atomically. Polars alone: pyarrow would add ~50 ms of imports to every render,
    and its builders from Python values import pandas (~0.35 s), against ~0.25 s of drawing and encoding for a
    40-frame render."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as partial:
        pl.DataFrame(rows, schema=SCHEMA).write_parquet(partial)
    return path
