"""Points aggregated as the devkit's `LidarPointCloud.from_file_multisweep` / `RadarPointCloud.from_file_multisweep`
do (`nuparquet.frames.sweeps.multisweep`, the one implementation), as training arrays: the point columns with the
time lag appended, float32."""

from __future__ import annotations

import numpy as np

from nuparquet.frames.sweeps import multisweep


def devkit_points(dataset, sample_token: str, channel: str, ref_channel: str, sweeps: int, min_distance_m: float,
                  *, radar_filters: bool = True) -> tuple[np.ndarray, int]:
    """(P, F + 1) float32 the sample's `channel` keyframe and up to `sweeps` previous sweeps (the devkit's
    `nsweeps = sweeps + 1`) in the `ref_channel` keyframe's frame, every cloud without its points closer than
    `min_distance_m` on x and y (the keyframe's too, as the devkit removes them), then the devkit's `times` [s]
    as the last column; and the number of previous sweeps found."""
    found = multisweep(dataset, sample_token, channel, ref_channel, sweeps + 1, min_distance_m,
                       radar_filters=radar_filters)
    points = np.empty((len(found.points), found.points.shape[1] + 1), dtype=np.float32)
    points[:, :-1] = found.points
    points[:, -1] = found.times_s
    return points, len(found.tokens) - 1


def radar_points(dataset, sample_token: str, radars: tuple[str, ...], ref_channel: str, sweeps: int,
                 min_distance_m: float, radar_filters: bool = True) -> np.ndarray:
    """(R, F + 1) float32 every radar of `radars` (at least one) in that order, each as `devkit_points` gives it,
    concatenated."""
    return np.concatenate([devkit_points(dataset, sample_token, channel, ref_channel, sweeps, min_distance_m,
                                         radar_filters=radar_filters)[0] for channel in radars])
