"""The boxes of one evaluation, ground truth or predictions, as aligned arrays (the devkit's `EvalBoxes` of
`DetectionBox`es, one array per field): the package's `Cuboids` with the evaluation's columns beside them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.geometry.cuboids import CuboidRows, Cuboids


@dataclass(frozen=True)
class Boxes(CuboidRows):
    """N boxes in the devkit's order (`EvalBoxes.all`: by sample, then as listed in it).

    cuboids: (N,) the boxes, global (`translation_m`, `size_wlh_m` [width, length, height], `rotation_wxyz`).
    sample_index: (N,) int64 index into the evaluation's samples (`GroundTruth.samples`).
    class_index: (N,) int64 index into the configuration's class names.
    velocity_mps: (N, 2) global [vx, vy] (NaN: unknown).
    attribute: (N,) str, '' for none. score: (N,) float64 (-1 for ground truth, as the devkit).
    num_pts: (N,) int64 lidar + radar points in a ground-truth box; -1 ("not counted") for predictions.
    """

    sample_index: np.ndarray
    class_index: np.ndarray
    velocity_mps: np.ndarray
    attribute: np.ndarray
    score: np.ndarray
    num_pts: np.ndarray

    @classmethod
    def empty(cls) -> Boxes:
        return cls(cuboids=Cuboids.empty(), sample_index=np.zeros(0, np.int64), class_index=np.zeros(0, np.int64),
                   velocity_mps=np.zeros((0, 2)), attribute=np.zeros(0, object), score=np.zeros(0),
                   num_pts=np.zeros(0, np.int64))
