"""The devkit's `nuscenes.map_expansion.arcline_path_utils`, every function, over nuparquet's arcline arithmetic
(`nuparquet.map.centerlines`: the devkit's formulas in its order, vectorised; `nuparquet.map.arcline`: lengths,
projection, curvature).

An arcline path is a dict (`start_pose`, `shape`, `radius`, `segment_length`) as the map's `arcline_path_3` holds
it; a lane is a list of them. Poses are (x, y, yaw) tuples of Python floats, as the devkit's. The trigonometry is
numpy's (the devkit's is `math`'s): the same to the last bit or within one rounding (CONTRACTS.md).
"""

from __future__ import annotations

from typing import Any, Dict, List, Tuple

import numpy as np

from nuparquet.map import arcline, centerlines

# (x, y, yaw) in global frame
Pose = Tuple[float, float, float]

ArcLinePath = Dict[str, Any]


def _floats(*values) -> tuple:
    return tuple(float(v) for v in values)


def principal_value(angle_in_radians: float) -> float:
    """The angle in [-pi, pi)."""
    return float(centerlines._principal(np.float64(angle_in_radians)))


def compute_segment_sign(arcline_path: ArcLinePath) -> Tuple[int, int, int]:
    """The turn of each of the path's three segments: 1 left, -1 right, 0 straight (from its shape)."""
    first, middle, last = centerlines._signs([arcline_path['shape']])[0].astype(int).tolist()
    return first, middle, last


def get_transformation_at_step(pose: Pose, step: float) -> Pose:
    """The transformation `step` metres along a segment whose Lie algebra pose is `pose`."""
    return _floats(*centerlines._step(np.float64(pose[2]), np.float64(step), pose[0], pose[1]))


def apply_affine_transformation(pose: Pose, transformation: Pose) -> Pose:
    """`transformation` applied to `pose`."""
    return _floats(*centerlines._apply(np.float64(pose[0]), np.float64(pose[1]), np.float64(pose[2]),
                                       transformation[0], transformation[1], transformation[2]))


def _get_lie_algebra(segment_sign: Tuple[int, int, int], radius: float) -> List[Tuple[float, float, float]]:
    """The Lie algebra pose of each segment: (1, 0, curvature)."""
    return [(1.0, 0.0, segment_sign[0] / radius),
            (1.0, 0.0, segment_sign[1] / radius),
            (1.0, 0.0, segment_sign[2] / radius)]


def _path_arrays(arcline_path: ArcLinePath):
    start = np.asarray([arcline_path['start_pose']], np.float64).reshape(1, 3)
    lengths = np.asarray([arcline_path['segment_length']], np.float64).reshape(1, 3)
    curvature = centerlines._signs([arcline_path['shape']]) / np.float64(arcline_path['radius'])
    return start, curvature, lengths


def pose_at_length(arcline_path: ArcLinePath, pos: float) -> Tuple[float, float, float]:
    """The pose `pos` metres along the path (clipped to its length; `pos` >= 1e-6)."""
    assert 1e-6 <= pos
    start, curvature, lengths = _path_arrays(arcline_path)
    x, y, yaw = centerlines._pose_at_length(start, curvature, lengths, np.array([pos], np.float64))
    return _floats(x[0], y[0], yaw[0])


def discretize(arcline_path: ArcLinePath, resolution_meters: float) -> List[Pose]:
    """The path's poses, about `resolution_meters` apart (both ends included)."""
    start, _, lengths = _path_arrays(arcline_path)
    poses, _ = centerlines.discretize_paths(start, [arcline_path['shape']],
                                            np.array([arcline_path['radius']], np.float64), lengths,
                                            resolution_meters)
    return [tuple(p) for p in poses.tolist()]


def discretize_lane(lane: List[ArcLinePath], resolution_meters: float) -> List[Pose]:
    """Every path's poses, path after path."""
    poses, _ = centerlines.discretize_lanes([list(lane)], resolution_meters)
    return [tuple(p) for p in poses.tolist()]


def length_of_lane(lane: List[ArcLinePath]) -> float:
    """The lane's length in metres."""
    return arcline.length_of_lane(lane)


def project_pose_to_lane(pose: Pose, lane: List[ArcLinePath], resolution_meters: float = 0.5) -> Tuple[Pose, float]:
    """The lane's discretised pose nearest `pose`'s (x, y) and the distance along the lane the devkit gives it
    (its index times `resolution_meters`); the query's heading is not used."""
    return arcline.project_pose_to_lane(pose, lane, resolution_meters)


def _find_index(distance_along_lane: float, lengths: List[float]) -> int:
    """The first path (or segment) whose cumulative end is at or beyond the distance."""
    return arcline._find_index(distance_along_lane, lengths)


def get_curvature_at_distance_along_lane(distance_along_lane: float, lane: List[ArcLinePath]) -> float:
    """Unsigned curvature (1 / metres) of the lane `distance_along_lane` along it."""
    return arcline.curvature_at_distance(distance_along_lane, lane)
