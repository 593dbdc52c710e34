"""The boxes of one evaluation, ground truth or predictions, as aligned arrays (the devkit's `EvalBoxes` of
`DetectionBox`es, one array per field)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


@dataclass(frozen=True)
class Boxes:
    """N boxes in the devkit's order (`EvalBoxes.all`: by sample, then as listed in it).

    sample_index: (N,) int64 index into the evaluation's samples (`GroundTruth.samples`).
    class_index: (N,) int64 index into the configuration's class names.
    translation_m: (N, 3), size_wlh_m: (N, 3) [width, length, height], rotation_wxyz: (N, 4), all global.
    velocity_mps: (N, 2) global [vx, vy] (NaN: unknown).
    attribute: (N,) str, '' for none. score: (N,) float64 (-1 for ground truth, as the devkit).
    num_pts: (N,) int64 lidar + radar points in a ground-truth box; -1 ("not counted") for predictions.
    """

    sample_index: np.ndarray
    class_index: np.ndarray
    translation_m: np.ndarray
    size_wlh_m: np.ndarray
    rotation_wxyz: np.ndarray
    velocity_mps: np.ndarray
    attribute: np.ndarray
    score: np.ndarray
    num_pts: np.ndarray

    def __len__(self) -> int:
        return len(self.sample_index)

    def take(self, rows) -> Boxes:
        """The boxes at `rows` (an index array or a boolean mask), in that order."""
        return Boxes(**{f.name: getattr(self, f.name)[rows] for f in fields(self)})

    @classmethod
    def empty(cls) -> Boxes:
        return cls(sample_index=np.zeros(0, np.int64), class_index=np.zeros(0, np.int64),
                   translation_m=np.zeros((0, 3)), size_wlh_m=np.zeros((0, 3)), rotation_wxyz=np.zeros((0, 4)),
                   velocity_mps=np.zeros((0, 2)), attribute=np.zeros(0, object), score=np.zeros(0),
                   num_pts=np.zeros(0, np.int64))
