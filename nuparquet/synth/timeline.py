"""When each sample and each sensor reading of one scene happens.

Like the real data: samples (keyframes) at 2 Hz stamped with the LIDAR_TOP keyframe time; every channel has
exactly one keyframe reading per sample close to the sample time (cameras fire 2-44 ms before the lidar,
radars within +-35 ms); sweeps lie strictly between two keyframes of their channel, so every channel's chain
starts and ends on a keyframe (no sweeps before the first or after the last keyframe of a scene, as in the
real scenes). A sweep belongs to (`sample_token`) the keyframe sample that follows it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.synth.taxonomy import CHANNELS, KEYFRAME_INTERVAL_US, Channel

SAMPLE_JITTER_US = 1_500
RADAR_KEYFRAME_SPREAD_US = 35_000
SWEEP_JITTER_US = 1_000


@dataclass(frozen=True)
class Timeline:
    """Timestamps of one scene. Frames (sample_data rows) are ordered by channel, then time."""

    sample_timestamp_us: np.ndarray  # (K,) int64, strictly increasing
    frame_channel: np.ndarray  # (M,) int64 index into the rig's channels
    frame_timestamp_us: np.ndarray  # (M,) int64, increasing within a channel
    frame_is_key_frame: np.ndarray  # (M,) bool
    frame_sample_index: np.ndarray  # (M,) int64: keyframes their sample, sweeps the next keyframe's sample
    frame_prev: np.ndarray  # (M,) int64 index of the previous reading of the same channel, -1 at the start
    frame_next: np.ndarray  # (M,) int64, -1 at the end


def make_timeline(rng: np.random.Generator, start_us: int, n_samples: int,
                  channels: tuple[Channel, ...] = CHANNELS) -> Timeline:
    sample_us = (start_us + np.arange(n_samples, dtype=np.int64) * KEYFRAME_INTERVAL_US
                 + rng.integers(-SAMPLE_JITTER_US, SAMPLE_JITTER_US + 1, n_samples))
    sample_us[0] = start_us
    channel_of_frame, stamps, key, sample_index = [], [], [], []
    for c, channel in enumerate(channels):
        if channel.modality == "lidar":
            keyframe_us = sample_us.copy()  # the sample timestamp *is* the lidar keyframe time
        elif channel.modality == "radar":
            keyframe_us = sample_us + rng.integers(-RADAR_KEYFRAME_SPREAD_US, RADAR_KEYFRAME_SPREAD_US + 1, n_samples)
        else:
            keyframe_us = sample_us + channel.keyframe_offset_us + rng.integers(-2_000, 2_001, n_samples)
        lo, hi = channel.sweeps_per_interval
        n_sweeps = rng.integers(lo, hi + 1, max(n_samples - 1, 0))
        interval = np.repeat(np.arange(n_samples - 1), n_sweeps)  # (S,) keyframe interval of each sweep
        j = np.arange(interval.size) - np.repeat(np.cumsum(n_sweeps) - n_sweeps, n_sweeps) + 1  # 1..n in interval
        span_us = (keyframe_us[1:] - keyframe_us[:-1])[interval]
        fraction = j / (n_sweeps[interval] + 1)
        sweep_us = (keyframe_us[interval] + np.round(fraction * span_us).astype(np.int64)
                    + rng.integers(-SWEEP_JITTER_US, SWEEP_JITTER_US + 1, interval.size))
        t = np.concatenate([keyframe_us, sweep_us])
        order = np.argsort(t, kind="stable")
        stamps.append(t[order])
        key.append(np.r_[np.ones(n_samples, bool), np.zeros(interval.size, bool)][order])
        sample_index.append(np.r_[np.arange(n_samples), interval + 1][order])
        channel_of_frame.append(np.full(t.size, c, dtype=np.int64))
    frame_channel = np.concatenate(channel_of_frame)
    m = frame_channel.size
    same_as_prev = np.r_[False, frame_channel[1:] == frame_channel[:-1]]
    same_as_next = np.r_[frame_channel[:-1] == frame_channel[1:], False]
    index = np.arange(m)
    return Timeline(
        sample_timestamp_us=sample_us,
        frame_channel=frame_channel,
        frame_timestamp_us=np.concatenate(stamps),
        frame_is_key_frame=np.concatenate(key),
        frame_sample_index=np.concatenate(sample_index).astype(np.int64),
        frame_prev=np.where(same_as_prev, index - 1, -1),
        frame_next=np.where(same_as_next, index + 1, -1),
    )
