"""The output plan: how many pictures, at which times, and which tile sources fill each picture.

A picture is rows of tiles (`mosaic`). Every tile comes from a `TileSource`, which knows for each output t
what to read (on a decode thread) and how to draw it (on the main thread). Camera tiles
(`render.camera_tile.CameraTile`) show the camera frame the plan matched to t; a bird's-eye-view tile (the
map issue) will be one more `TileSource` drawing the map, boxes and points at `TilePlan.times_us[t]`, with
no image file, placed in the layout beside the cameras.

Which camera frame goes to which output (`camera_rows_per_output`):
- one channel: every frame, in time order;
- "all", keyframes: one output per sample, each camera showing its keyframe of that sample;
- "all", every frame: devkit `render_scene`'s time steps between the first and last sample (`mosaic`).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import polars as pl

from nuparquet.rendering.mosaic import match_frames_by_time, mosaic_size, time_steps_us


@dataclass(frozen=True)
class TileLoad:
    """What a tile source read for one output: `data` for its `draw`, and the files it found missing."""

    data: Any = None
    missing: tuple[str, ...] = ()


class TileSource(Protocol):
    """One tile of every output picture."""

    label: str  # names the tile (a placeholder shows it when there is nothing to draw)

    def key(self, t: int) -> Hashable | None:
        """What output t shows: equal keys on consecutive outputs reuse the drawn tile; None shows nothing."""

    def load(self, t: int) -> TileLoad:
        """Read what output t needs (image files, point clouds); runs on a decode thread, ahead of drawing."""

    def draw(self, t: int, loaded: TileLoad) -> np.ndarray | None:
        """The (tile height, tile width, 3) BGR tile of output t, or None when there is nothing to show."""

    def shows(self, t: int) -> tuple[str, int] | None:
        """(sample_data token, timestamp) of the frame output t shows, or None (the frame index)."""


class RowTile:
    """`key` and `shows` for tile sources that show one row of their frames per output (`rows`: (T,) int, -1 =
    nothing; `tokens`, `timestamps_us`: the sample_data token and timestamp of each of their rows)."""

    rows: np.ndarray
    tokens: tuple[str, ...] = ()
    timestamps_us: np.ndarray | None = None

    def key(self, t: int) -> int | None:
        row = int(self.rows[t])
        return row if row >= 0 else None

    def shows(self, t: int) -> tuple[str, int] | None:
        row = self.key(t)
        if row is None or not len(self.tokens):
            return None
        return str(self.tokens[row]), int(self.timestamps_us[row])


@dataclass(frozen=True)
class TilePlan:
    """T output pictures: their times and the tile sources in rows (front row first, left to right)."""

    times_us: np.ndarray  # (T,) float64 output times, microseconds
    layout: tuple[tuple[TileSource, ...], ...]
    tile_size: tuple[int, int]  # (width, height) of every tile

    def __len__(self) -> int:
        return len(self.times_us)

    @property
    def sources(self) -> tuple[TileSource, ...]:
        """Every tile source, row by row (the order `mosaic.compose` places tiles in)."""
        return tuple(source for row in self.layout for source in row)

    @property
    def row_lengths(self) -> tuple[int, ...]:
        return tuple(len(row) for row in self.layout)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of an output picture."""
        return mosaic_size(self.row_lengths, *self.tile_size)


def tile_size(cameras: pl.DataFrame, scale: float) -> tuple[int, int]:
    """(width, height) of a tile: the largest camera image scaled by `scale` (at least 2 x 2 pixels)."""
    width, height = int(cameras["width"].max()), int(cameras["height"].max())
    return max(2, round(width * scale)), max(2, round(height * scale))


def camera_rows_per_output(
    cameras: pl.DataFrame, samples: pl.DataFrame, channels: Sequence[str], *, mosaic: bool, all_frames: bool,
    fps: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Which camera row goes into each tile of each output.

    Args:
        cameras: camera rows sorted by channel, then timestamp (`SceneRows.cameras`).
        samples: the scene's samples (token, timestamp).
        channels: (C,) the tile channels, in `TilePlan.sources` order.
        mosaic: several cameras matched per output (channel "all") rather than one camera's every row.
        all_frames: sweeps included. fps: output rate (the devkit's time step of an all-frames mosaic).

    Returns:
        times_us: (T,) float64 output times. rows: (T, C) int64 rows of `cameras` (-1: no frame for that tile).
    """
    timestamps = cameras["timestamp"].to_numpy()
    if not mosaic:
        return timestamps.astype(np.float64), np.arange(cameras.height, dtype=np.int64)[:, None]
    column_of = {channel: index for index, channel in enumerate(channels)}
    if not all_frames:
        keyframes = cameras.with_row_index("row").filter(pl.col("is_key_frame"))
        by_sample = (
            keyframes.group_by("sample_token")
            .agg(pl.col("timestamp").min().alias("t"), pl.col("channel"), pl.col("row"))
            .sort("t")
        )
        rows = np.full((by_sample.height, len(channels)), -1, dtype=np.int64)
        exploded = by_sample.with_row_index("output").explode("channel", "row")
        columns = np.array([column_of[c] for c in exploded["channel"].to_list()], dtype=np.int64)
        rows[exploded["output"].to_numpy(), columns] = exploded["row"].to_numpy()
        return by_sample["t"].to_numpy().astype(np.float64), rows
    # Every frame: devkit render_scene, time steps of 1 / fps from the scene's first to its last sample.
    samples = samples.sort("timestamp")
    times_us = time_steps_us(int(samples["timestamp"][0]), int(samples["timestamp"][-1]), fps)
    starts = (cameras["sample_token"] == samples["token"][0]).to_numpy() & cameras["is_key_frame"].to_numpy()
    channel_of_row = cameras["channel"].to_numpy()
    rows = np.full((len(times_us), len(channels)), -1, dtype=np.int64)
    for column, channel in enumerate(channels):  # one pass per camera
        channel_rows = np.flatnonzero(channel_of_row == channel)
        if len(channel_rows) == 0:
            continue
        # The devkit starts each camera at its keyframe of the first sample.
        start = int(np.argmax(starts[channel_rows])) if starts[channel_rows].any() else 0
        rows[:, column] = channel_rows[match_frames_by_time(timestamps[channel_rows], start, times_us)]
    return times_us, rows
