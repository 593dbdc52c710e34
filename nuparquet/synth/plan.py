"""The dataset-level plan: which logs exist (vehicle, location, date), which scenes each log holds and when they
start, and each log's sensor rig (calibrations in the style of the real nuScenes cars).

All of it comes from one seeded RNG, so the plan is a pure function of (seed, number of scenes).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import numpy as np

from nuparquet.synth.rigid import quat_from_axis_angle, quat_from_matrix, quat_from_yaw, quat_multiply
from nuparquet.synth.taxonomy import CHANNELS, LOCATIONS, Channel, Location
from nuparquet.synth.tokens import random_tokens

SCENES_PER_LOG = 12.5  # nuScenes trainval: 850 scenes in 68 logs
SCENE_GAP_S = (5.0, 90.0)  # idle time between two scenes of one log
FIRST_DATE = dt.date(2018, 7, 23)

# Maps the camera's optical frame (x right, y down, z forward) onto a forward-looking body (x forward, y left,
# z up): columns are the images of the optical axes.
_BODY_FROM_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class Rig:
    """The sensor channels of a car and the calibration of each, in `channels` order."""

    channels: tuple[Channel, ...]
    ego_from_sensor_translation_m: np.ndarray  # (C, 3)
    ego_from_sensor_rotation: np.ndarray  # (C, 4) quaternions [w, x, y, z]
    intrinsic: np.ndarray  # (C, 3, 3); all zeros for non-cameras (written as [])


@dataclass(frozen=True)
class LogPlan:
    token: str
    logfile: str
    vehicle: str
    date_captured: str
    location: Location
    rig: Rig
    scene_indices: tuple[int, ...]
    scene_start_us: tuple[int, ...]  # UTC microseconds of each scene's first sample


def make_rig(rng: np.random.Generator, channels: tuple[Channel, ...] = CHANNELS) -> Rig:
    """One car's calibration: the nominal mounting of each channel, perturbed by millimetres and fractions of
    a degree as the real cars' calibrations differ."""
    n = len(channels)
    translation = np.array([c.translation_m for c in channels]) + rng.normal(0.0, 0.01, (n, 3))
    translation = np.round(translation, 6)
    rotation = np.zeros((n, 4))
    intrinsic = np.zeros((n, 3, 3))
    base = quat_from_matrix(_BODY_FROM_OPTICAL)
    for i, channel in enumerate(channels):
        yaw = np.deg2rad(channel.yaw_deg + rng.normal(0.0, 0.5 if channel.modality != "lidar" else 0.1))
        if channel.modality == "radar":  # real radar calibrations are pure yaw
            rotation[i] = quat_from_yaw(yaw)
            continue
        pitch, roll = np.deg2rad(rng.normal(0.0, [0.6, 0.3]))
        body = quat_multiply(quat_multiply(quat_from_yaw(yaw), quat_from_axis_angle((0.0, 1.0, 0.0), pitch)),
                             quat_from_axis_angle((1.0, 0.0, 0.0), roll))
        if channel.modality == "camera":
            rotation[i] = quat_multiply(body, base)
            focal = channel.focal_px + rng.normal(0.0, 5.0)
            width_px, height_px = channel.size_px
            cx = width_px / 2 + rng.normal(15.0, 12.0)
            cy = height_px / 2 + rng.uniform(0.0, 50.0)
            intrinsic[i] = [[focal, 0.0, cx], [0.0, focal, cy], [0.0, 0.0, 1.0]]
        else:
            rotation[i] = body
    rotation /= np.linalg.norm(rotation, axis=1, keepdims=True)
    return Rig(channels, translation, rotation, intrinsic)


def plan_logs(seed: int, scenes: int, scene_duration_s: float, channels: tuple[Channel, ...] = CHANNELS
              ) -> list[LogPlan]:
    """Spread `scenes` over logs (at least two logs in two locations when there are two scenes or more),
    consecutive scene indices per log; every car carries the sensor `channels`."""
    rng = np.random.default_rng([seed, 0])
    n_logs = min(scenes, max(2, round(scenes / SCENES_PER_LOG)))
    log_of_scene = (np.arange(scenes) * n_logs) // scenes
    logs = []
    for log_index in range(n_logs):
        location = LOCATIONS[log_index % len(LOCATIONS)]
        vehicle = location.vehicles[(log_index // len(LOCATIONS)) % len(location.vehicles)]
        date = FIRST_DATE + dt.timedelta(days=int(rng.integers(0, 100)))
        local_start = dt.datetime(date.year, date.month, date.day, int(rng.integers(8, 18)),
                                  int(rng.integers(0, 60)), int(rng.integers(0, 60)),
                                  tzinfo=dt.timezone(dt.timedelta(hours=location.utc_offset_h)))
        offset = f"{'+' if location.utc_offset_h >= 0 else '-'}{abs(location.utc_offset_h):02d}00"
        logfile = f"{vehicle}-{local_start:%Y-%m-%d-%H-%M-%S}{offset}"
        scene_indices = tuple(int(i) for i in np.flatnonzero(log_of_scene == log_index))
        # Integer arithmetic from an integer epoch: no float rounding, no wall clock.
        start_us = int(local_start.timestamp()) * 1_000_000 + int(rng.integers(0, 1_000_000))
        gaps_us = rng.uniform(*SCENE_GAP_S, len(scene_indices)) * 1e6
        starts = start_us + np.cumsum(np.r_[0.0, gaps_us[:-1] + scene_duration_s * 1e6]).astype(np.int64)
        logs.append(LogPlan(
            token=random_tokens(rng, 1)[0], logfile=logfile, vehicle=vehicle, date_captured=date.isoformat(),
            location=location, rig=make_rig(rng, channels), scene_indices=scene_indices,
            scene_start_us=tuple(int(s) for s in starts),
        ))
    return logs
