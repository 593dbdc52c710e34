"""The road and how things travel along it: a smooth centreline parametrised by arc length `s` (gentle
meander, a few turns of up to 90 degrees) and smooth speed profiles (cruising, slow urban driving, stop and go,
waiting at a light). The ego car and every moving object of a scene follow these.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_SPEED_MPS = 15.0
MAX_CURVATURE_PER_M = 1.0 / 38.0  # keeps the innermost row (15.5 m off the centreline) from folding over
PATH_STEP_M = 0.5
SPEED_KNOT_SPACING_S = 3.0


@dataclass(frozen=True)
class Road:
    s_m: np.ndarray  # (P,) arc-length grid
    xy_m: np.ndarray  # (P, 2) global centreline
    heading_rad: np.ndarray  # (P,) unwrapped heading of the centreline

    def at(self, s_m: np.ndarray, lateral_m: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Global (..., 2) position and heading at arc length s and lateral offset (positive = left)."""
        heading = np.interp(s_m, self.s_m, self.heading_rad)
        x = np.interp(s_m, self.s_m, self.xy_m[:, 0]) - np.sin(heading) * lateral_m
        y = np.interp(s_m, self.s_m, self.xy_m[:, 1]) + np.cos(heading) * lateral_m
        return np.stack([x, y], axis=-1), heading


def _smooth_profile(t_s: np.ndarray, knots: np.ndarray, spacing_s: float) -> np.ndarray:
    """Values at times t_s that pass through `knots` (one every spacing_s from t_s[0]) with zero slope at each
    knot: smooth (C1) speed profiles without overshoot."""
    u = (t_s - t_s[0]) / spacing_s
    k = np.clip(np.floor(u).astype(int), 0, knots.size - 2)
    blend = 0.5 - 0.5 * np.cos(np.pi * np.clip(u - k, 0.0, 1.0))
    return knots[k] + (knots[k + 1] - knots[k]) * blend


def _speed_knots(rng: np.random.Generator, n: int, style: str) -> np.ndarray:
    if style == "cruise":
        knots = rng.uniform(7.0, 14.0, n)
    elif style == "urban":
        knots = rng.uniform(2.0, 9.0, n)
    elif style == "stop_and_go":
        knots = rng.uniform(4.0, 11.0, n)
        stop = rng.integers(1, max(n - 2, 2))
        knots[stop:stop + 2] = 0.0
    else:  # "waiting": standing still, maybe pulling away at the end
        knots = np.zeros(n)
        go = int(n * rng.uniform(0.5, 1.0))
        knots[go:] = rng.uniform(1.0, 5.0, n - go)
    return np.clip(knots, 0.0, MAX_SPEED_MPS)


def travel_profile(rng: np.random.Generator, t_s: np.ndarray, style: str) -> tuple[np.ndarray, np.ndarray]:
    """(T,) speed [m/s] and distance travelled [m] (0 at t_s == 0) on the dense time grid."""
    spacing_s = SPEED_KNOT_SPACING_S
    n = int(np.ceil((t_s[-1] - t_s[0]) / spacing_s)) + 2
    speed = np.clip(_smooth_profile(t_s, _speed_knots(rng, n, style), spacing_s), 0.0, MAX_SPEED_MPS)
    distance = np.r_[0.0, np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t_s))]
    return speed, distance - np.interp(0.0, t_s, distance)


def make_road(rng: np.random.Generator, s_lo: float, s_hi: float, ego_end_m: float) -> tuple[Road, list[float]]:
    s = np.arange(s_lo, s_hi + PATH_STEP_M, PATH_STEP_M)
    wavelength = rng.uniform(150.0, 400.0)
    curvature = 0.003 * np.sin(2 * np.pi * s / wavelength + rng.uniform(0, 2 * np.pi))  # gentle meander
    turns = []
    for _ in range(rng.choice([0, 1, 1, 2])):
        angle = rng.choice([-1.0, 1.0]) * rng.uniform(0.3, np.pi / 2)
        length = max(80.0 * abs(angle), 50.0) + rng.uniform(0.0, 40.0)  # peak curvature 2*angle/length <= 1/40
        start = rng.uniform(-0.5 * length, max(ego_end_m - 0.5 * length, -0.5 * length + 1.0))
        inside = (s >= start) & (s <= start + length)
        curvature[inside] += angle / length * (1 - np.cos(2 * np.pi * (s[inside] - start) / length))
        turns.append(angle)
    curvature = np.clip(curvature, -MAX_CURVATURE_PER_M, MAX_CURVATURE_PER_M)
    heading = np.r_[0.0, np.cumsum(0.5 * (curvature[1:] + curvature[:-1]) * PATH_STEP_M)]
    heading += rng.uniform(-np.pi, np.pi) - np.interp(0.0, s, heading)
    step = np.stack([np.cos(heading), np.sin(heading)], axis=-1) * PATH_STEP_M
    xy = np.r_[np.zeros((1, 2)), np.cumsum(0.5 * (step[1:] + step[:-1]), axis=0)]
    origin = rng.uniform([300.0, 300.0], [2500.0, 1800.0])  # map-frame coordinates like the real maps'
    xy += origin - np.array([np.interp(0.0, s, xy[:, 0]), np.interp(0.0, s, xy[:, 1])])
    return Road(s, xy, heading), turns
