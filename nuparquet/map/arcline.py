"""The devkit's `arcline_path_utils` beyond discretising (`map.centerlines`): a pose projected onto a lane, a lane's
length and its curvature at a distance along it, with the devkit's arithmetic and quirks.

A lane is a list of arcline paths (dicts with `start_pose`, `shape`, `radius`, `segment_length`), as the map's
`arcline_path_3` holds them (`MapLayers.arcline_path(token)`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from nuparquet.map.centerlines import discretize_lanes

Pose = tuple[float, float, float]


def length_of_lane(lane: Sequence[dict]) -> float:
    """The lane's length, metres: every segment of every path, summed in the devkit's order."""
    return sum(sum(path["segment_length"]) for path in lane)


def project_pose_to_lane(pose: Sequence[float], lane: Sequence[dict], resolution_m: float = 0.5) -> tuple[Pose, float]:
    """The lane's discretised pose (`discretize_lane` at `resolution_m`) nearest to `pose`'s (x, y), and the distance
    along the lane the devkit reports for it: its index times `resolution_m` (the nominal step, not the step each path
    was actually cut into, as `arcline_path_utils.project_pose_to_lane` does). The query's heading is not used."""
    poses, _ = discretize_lanes([list(lane)], resolution_m)
    if not len(poses):
        raise ValueError("the lane has no arcline path to project onto")
    index = int(np.linalg.norm(poses[:, :2] - np.asarray(pose[:2], dtype=np.float64), axis=1).argmin())
    x, y, yaw = poses[index].tolist()
    return (x, y, yaw), index * resolution_m


def _find_index(distance_m: float, cumulative: np.ndarray) -> int:
    """The first path (or segment) whose cumulative end is at or beyond `distance_m`; the only one when there is one."""
    if len(cumulative) == 1:
        return 0
    return min(index for index, end in enumerate(cumulative) if distance_m <= end)


def curvature_at_distance(distance_m: float, lane: Sequence[dict]) -> float:
    """Unsigned curvature (1 / metres) of the lane `distance_m` along it: 0 on a straight segment, 1 / radius on an
    arc (`arcline_path_utils.get_curvature_at_distance_along_lane`). ValueError beyond the lane's end, as the
    devkit's `min()` of nothing."""
    totals = np.cumsum([sum(path["segment_length"]) for path in lane])
    path_index = _find_index(distance_m, totals)
    path = lane[path_index]
    along = distance_m - totals[path_index - 1] if path_index > 0 else distance_m
    segment = _find_index(along, np.cumsum(path["segment_length"]))
    return 0 if path["shape"][segment] == "S" else 1 / path["radius"]
