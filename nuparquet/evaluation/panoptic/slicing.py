"""The panoptic metrics per slice (`by=`): a slice is the frames of some scenes (`location`, `night`, `rain`,
`scene`, or any column of the `scenes` dataset, labelled as the detection slices label a sample:
`nuparquet.evaluation.slices.scene_labels`), evaluated as a whole evaluation is, with its own counts (and, for
tracking, its own scenes' tracks), so a slice's dict is the devkit's for those scenes alone. Points have no slice
of their own here (an instance spans ranges), so `distance` is lidarseg's only."""

from __future__ import annotations

from collections.abc import Sequence

import polars as pl

from nuparquet.errors import InputError, UsageError
from nuparquet.evaluation.panoptic.quality import PanopticQuality
from nuparquet.evaluation.panoptic.segments import FrameSegments
from nuparquet.evaluation.panoptic.tracking import PanopticTracking
from nuparquet.evaluation.slices import SCENE_NAMED, scene_labels

SEGMENTATION_COLUMNS = ("PQ", "SQ", "RQ", "mIoU", "PQ_dagger")
TRACKING_COLUMNS = ("PAT", "LSTQ", "PTQ", "sPTQ", "TQ", "MOTSA")


def check_by(by: Sequence[str], scene_columns: Sequence[str], task: str) -> None:
    for name in by:
        if name not in SCENE_NAMED and name not in scene_columns:
            raise UsageError(f"--by {name}: --task {task} slices by {', '.join(SCENE_NAMED)} or a column of scenes "
                             f"({', '.join(scene_columns)})")


class SliceEvaluations:
    """One segmentation (and tracking) evaluation per (dimension, slice), added to frame by frame.

    frame_scenes: one row per evaluated frame, in the evaluation's order, with its scene's columns."""

    def __init__(self, by: Sequence[str], frame_scenes: pl.DataFrame, bins: tuple[float, ...] | None,
                 min_inst_points: int, tracking: bool) -> None:
        self.by, self.min_inst_points, self.tracking = list(by), min_inst_points, tracking
        self.frame_label, self.order = {}, {}
        for name in self.by:
            self.frame_label[name], self.order[name] = scene_labels(name, frame_scenes, bins)
        self.quality: dict[tuple[str, str], PanopticQuality] = {}
        self.tracker: dict[tuple[str, str], PanopticTracking] = {}
        self.frames: dict[tuple[str, str], int] = {}

    def add(self, frame: int, scene: str, seg: FrameSegments) -> None:
        for name in self.by:
            key = (name, self.frame_label[name][frame])
            if key not in self.quality:
                self.quality[key] = PanopticQuality(self.min_inst_points)
                self.tracker[key] = PanopticTracking(self.min_inst_points) if self.tracking else None
                self.frames[key] = 0
            self.quality[key].add(seg)
            if self.tracking:
                self.tracker[key].add(scene, seg)
            self.frames[key] += 1

    def summaries(self) -> tuple[dict[tuple[str, str], dict], list[str]]:
        """({(by, slice): the devkit's result dict of the slice}, notes), dimensions in `by` order, slices in label
        order. A slice whose tracking the devkit could not score (no thing instance above the minimum: it divides
        by zero) has its segmentation dict only, and a note says so."""
        out, notes = {}, []
        for name in self.by:
            present = [label for (dim, label) in self.quality if dim == name]
            order = self.order[name]
            for label in ([x for x in order if x in present] if order is not None else sorted(present)):
                key = (name, label)
                out[key] = {"segmentation": self.quality[key].metrics()}
                if self.tracking:
                    try:
                        out[key]["tracking"] = self.tracker[key].metrics()
                    except InputError as exc:
                        notes.append(f"slice {name} {label}: no tracking figures ({exc})")
        return out, notes

    def table(self, summaries: dict[tuple[str, str], dict]) -> pl.DataFrame:
        """One row per slice: by, slice, frames, the segmentation's overall figures and, for tracking, its own
        (null where a slice has none)."""
        columns = [*SEGMENTATION_COLUMNS, *(TRACKING_COLUMNS if self.tracking else ())]
        rows = []
        for (by, label), metrics in summaries.items():
            figures = dict(metrics["segmentation"]["all"])
            if self.tracking:
                figures |= {k: metrics["tracking"]["all"][k] for k in TRACKING_COLUMNS} if "tracking" in metrics \
                    else dict.fromkeys(TRACKING_COLUMNS)
            rows.append({"by": by, "slice": label, "frames": self.frames[(by, label)],
                         **{c: figures[c] for c in columns}})
        schema = {"by": pl.String, "slice": pl.String, "frames": pl.Int64, **{c: pl.Float64 for c in columns}}
        return pl.DataFrame(rows, schema=schema)

