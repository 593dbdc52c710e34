"""The six cameras tiled into one picture, and which frame of each camera goes into each output picture.

Layout (as devkit `NuScenesExplorer.render_scene`, without its horizontal flip of the back row):

    CAM_FRONT_LEFT  CAM_FRONT  CAM_FRONT_RIGHT
    CAM_BACK_LEFT   CAM_BACK   CAM_BACK_RIGHT

Matching by time follows `render_scene` too: output time steps start one step after the scene's first
keyframe, every `1 / freq` seconds, while the previous step is before the last keyframe; at each step every
camera shows its first frame at or after the step (the devkit walks each camera's `next` chain forward
while the frame is older than the step), or its last frame once the scene's end is passed. Each camera's
chain starts at its keyframe of the first sample, so frames before it are never shown.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

MOSAIC_LAYOUT: tuple[tuple[str, ...], ...] = (
    ("CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_RIGHT"),
    ("CAM_BACK_LEFT", "CAM_BACK", "CAM_BACK_RIGHT"),
)
MOSAIC_CHANNELS: tuple[str, ...] = tuple(channel for row in MOSAIC_LAYOUT for channel in row)


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


def mosaic_size(tile_width: int, tile_height: int) -> tuple[int, int]:
    """(width, height) of the tiled picture: 3 x 2 tiles."""
    return 3 * tile_width, 2 * tile_height


def tile_cameras(tiles_bgr: Mapping[str, np.ndarray], tile_width: int, tile_height: int) -> np.ndarray:
    """Tile up to six (tile_height, tile_width, 3) images by channel name (see MOSAIC_LAYOUT).

    Channels that are absent stay black; every given tile must already have the tile size.

    Returns:
        (2 * tile_height, 3 * tile_width, 3) uint8.
    """
    width, height = mosaic_size(tile_width, tile_height)
    canvas = np.zeros((height, width, 3), dtype=np.uint8)
    for row, channels in enumerate(MOSAIC_LAYOUT):
        for column, channel in enumerate(channels):
            tile = tiles_bgr.get(channel)
            if tile is None:
                continue
            if tile.shape[:2] != (tile_height, tile_width):
                raise ValueError(f"{channel} tile is {tile.shape[1]}x{tile.shape[0]}, expected {tile_width}x{tile_height}")
            canvas[row * tile_height:(row + 1) * tile_height, column * tile_width:(column + 1) * tile_width] = tile
    return canvas
