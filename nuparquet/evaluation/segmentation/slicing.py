"""The lidarseg metrics per slice (`by=`): a slice is a set of points, its confusion matrix the sum of its points'
(the devkit's arithmetic, `confusion.frame_confusion`), its metrics the devkit's result dict of that matrix.

How points are placed in slices:
- by their frame's scene: `location`, `night`, `rain`, `scene`, or any column of the `scenes` dataset (as the
  detection slices place a sample: `nuparquet.evaluation.slices.scene_labels`);
- by their own xy distance from the lidar (`distance`: the point's range in the sensor frame, in half-open
  `--bins` metres [low, high), default 0-10-20-30-40-50, points beyond the last edge in "<edge>m+").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl

from nuparquet.errors import UsageError
from nuparquet.evaluation.segmentation.classes import COARSE_NAMES, NUM_CLASSES
from nuparquet.evaluation.segmentation.confusion import frame_confusion, lidarseg_metrics
from nuparquet.evaluation.slices import DEFAULT_DISTANCE_BINS_M, SCENE_NAMED, bin_labels, scene_labels

NAMED = ("distance", *SCENE_NAMED)


def check_by(by: Sequence[str], scene_columns: Sequence[str]) -> None:
    """UsageError for a dimension lidarseg cannot slice by (the point-level annotation columns do not apply)."""
    for name in by:
        if name not in NAMED and name not in scene_columns:
            raise UsageError(f"--by {name}: --task lidarseg slices by {', '.join(NAMED)} or a column of scenes "
                             f"({', '.join(scene_columns)})")


class SliceConfusions:
    """The confusion matrix of every (dimension, slice), added to frame by frame.

    frame_scenes: one row per evaluated frame (in the evaluation's order) with its scene's columns (`name`,
    `description`, `log_location` and any column `by` names)."""

    def __init__(self, by: Sequence[str], frame_scenes: pl.DataFrame, bins: tuple[float, ...] | None) -> None:
        self.by = list(by)
        self.edges = bins or DEFAULT_DISTANCE_BINS_M
        self.frame_label: dict[str, np.ndarray] = {}
        self.order: dict[str, list[str] | None] = {}
        for name in self.by:
            if name == "distance":
                self.order[name] = bin_labels(np.zeros(0), self.edges, "m")[1]
            else:
                self.frame_label[name], self.order[name] = scene_labels(name, frame_scenes, bins)
        self.confusion: dict[tuple[str, str], np.ndarray] = {}
        self.frames: dict[tuple[str, str], int] = {}

    def _add(self, key: tuple[str, str], confusion: np.ndarray) -> None:
        if key not in self.confusion:
            self.confusion[key] = np.zeros((NUM_CLASSES, NUM_CLASSES), dtype=np.int64)
            self.frames[key] = 0
        self.confusion[key] += confusion
        self.frames[key] += 1

    def add(self, frame: int, points_xy: np.ndarray, gt: np.ndarray, pred: np.ndarray,
            confusion: np.ndarray) -> None:
        """Frame number `frame` of the evaluation: its points' (P, 2) xy in the sensor frame [m], coarse (P,)
        ground truth and predictions, and its whole confusion matrix."""
        for name in self.by:
            if name != "distance":
                self._add((name, self.frame_label[name][frame]), confusion)
                continue
            labels, _ = bin_labels(np.hypot(points_xy[:, 0], points_xy[:, 1]), self.edges, "m")
            for label in dict.fromkeys(labels[labels != None].tolist()):  # noqa: E711 - object array
                inside = labels == label
                self._add((name, label), frame_confusion(gt[inside], pred[inside]))

    def summaries(self) -> dict[tuple[str, str], dict]:
        """{(by, slice): the devkit's result dict of the slice}, dimensions in `by` order, slices in label order."""
        out = {}
        for name in self.by:
            present = [label for (dim, label) in self.confusion if dim == name]
            order = self.order[name]
            labels = [label for label in order if label in present] if order is not None else sorted(present)
            for label in labels:
                out[(name, label)] = lidarseg_metrics(self.confusion[(name, label)])
        return out

    def table(self, summaries: dict[tuple[str, str], dict]) -> pl.DataFrame:
        """One row per slice: by, slice, frames (with a point in it), points (scored: neither class ignored),
        miou, freq_weighted_iou, and `iou_<class>` for each of the 16 classes."""
        classes = COARSE_NAMES[1:]
        rows = [{"by": by, "slice": label, "frames": self.frames[(by, label)],
                 "points": int(self.confusion[(by, label)].sum()), "miou": m["miou"],
                 "freq_weighted_iou": m["freq_weighted_iou"],
                 **{f"iou_{c}": m["iou_per_class"][c] for c in classes}}
                for (by, label), m in summaries.items()]
        schema = {"by": pl.String, "slice": pl.String, "frames": pl.Int64, "points": pl.Int64, "miou": pl.Float64,
                  "freq_weighted_iou": pl.Float64, **{f"iou_{c}": pl.Float64 for c in classes}}
        return pl.DataFrame(rows, schema=schema)
