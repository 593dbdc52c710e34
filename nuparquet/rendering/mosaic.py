"""Tiles placed into one picture, and which frame of each camera the devkit shows at each output time.

Layout: rows of tiles, front row first, each left to right (`nuparquet.channels.camera_layout`; for nuScenes
the devkit `NuScenesExplorer.render_scene` layout without its horizontal flip of the back row):

    CAM_FRONT_LEFT  CAM_FRONT  CAM_FRONT_RIGHT
    CAM_BACK_LEFT   CAM_BACK   CAM_BACK_RIGHT

Rows may differ in length (a Lyft rig has four front cameras and three back ones): the picture is as wide as
the longest row, and a shorter row is centred (its offset rounded down to whole pixels).

Matching by time follows `render_scene` too: output time steps start one step after the scene's first
keyframe, every `1 / freq` seconds, while the previous step is before the last keyframe; at each step every
camera shows its first frame at or after the step (the devkit walks each camera's `next` chain forward
while the frame is older than the step), or its last frame once the scene's end is passed. Each camera's
chain starts at its keyframe of the first sample, so frames before it are never shown.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def time_steps_us(first_keyframe_us: int, last_keyframe_us: int, freq_hz: float) -> np.ndarray:
    """The output times of devkit `render_scene`: t0 + k * step for k = 1, 2, ... while t0 + (k-1) * step < t_last.

    Computed with the devkit's own float accumulation (`current_time += time_step`), so the step count and
    the times agree with it exactly.

    Returns:
        (T,) float64 times in microseconds.
    """
    step_us = 1 / freq_hz * 1e6
    times = []
    current = first_keyframe_us
    while current < last_keyframe_us:  # scalar loop over T output times, as in the devkit (T ~ scene s * freq)
        current += step_us
        times.append(current)
    return np.asarray(times, dtype=np.float64)


def match_frames_by_time(timestamps_us: np.ndarray, start_index: int, times_us: np.ndarray) -> np.ndarray:
    """For each output time, the frame of one camera that devkit `render_scene` shows.

    Args:
        timestamps_us: (F,) sorted timestamps of the camera's frames.
        start_index: index of the camera's frame the devkit starts from (its keyframe of the first sample).
        times_us: (T,) output times (`time_steps_us`).

    Returns:
        (T,) int indices into `timestamps_us`: the first frame at or after each time, not before
        `start_index`, and the last frame when none is.
    """
    timestamps_us = np.asarray(timestamps_us)
    if len(timestamps_us) == 0:
        return np.full(len(times_us), -1, dtype=np.int64)
    first_not_older = np.searchsorted(timestamps_us, np.asarray(times_us), side="left")
    return np.clip(first_not_older, start_index, len(timestamps_us) - 1).astype(np.int64)


def mosaic_size(row_lengths: Sequence[int], tile_width: int, tile_height: int) -> tuple[int, int]:
    """(width, height) of the picture holding rows of `row_lengths` tiles: the longest row by the row count."""
    return max(row_lengths) * tile_width, len(row_lengths) * tile_height


def tile_origins(row_lengths: Sequence[int], tile_width: int, tile_height: int) -> list[tuple[int, int]]:
    """(x, y) of the top-left pixel of every tile, row by row, left to right; shorter rows centred."""
    widest = max(row_lengths)
    return [((widest - length) * tile_width // 2 + column * tile_width, row * tile_height)
            for row, length in enumerate(row_lengths) for column in range(length)]


def compose(tiles_bgr: Sequence[np.ndarray | None], row_lengths: Sequence[int], tile_width: int,
            tile_height: int) -> np.ndarray:
    """Place tiles (row by row, left to right, as `tile_origins`) into one black picture.

    A single tile is returned as it is. None leaves its place black; every tile must have the tile size.

    Returns:
        (height, width, 3) uint8 of `mosaic_size`.
    """
    if len(tiles_bgr) == 1 and tiles_bgr[0] is not None:
        return tiles_bgr[0]
    width, height = mosaic_size(row_lengths, tile_width, tile_height)
    canvas = np.zeros((height, width, 3), dtype=np.uint8)
    for tile, (x, y) in zip(tiles_bgr, tile_origins(row_lengths, tile_width, tile_height)):
        if tile is None:
            continue
        if tile.shape[:2] != (tile_height, tile_width):
            raise ValueError(f"tile is {tile.shape[1]}x{tile.shape[0]}, expected {tile_width}x{tile_height}")
        canvas[y:y + tile_height, x:x + tile_width] = tile
    return canvas
