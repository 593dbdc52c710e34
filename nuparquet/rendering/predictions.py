"""Predicted boxes drawn beside the ground truth (`render --predictions RESULTS [--score-threshold 0.3]`).

RESULTS is a detection submission (results.json: every box is drawn in one colour, PREDICTED_RGB), a tracking
submission (boxes with a "tracking_id": each track in its own colour, the same in every picture and every run,
`track_rgb`, and labelled "<id> <class> <score>"), or a directory written by `nuparquet eval` (its predictions/
dataset: true positives at the TP threshold in TP_RGB, false positives in FP_RGB, boxes the evaluation left out,
beyond a class range or in a bicycle rack, in FILTERED_RGB). Every picture that draws them says what the colours
mean (`Predictions.legend`).
Predictions belong to samples, so they are drawn on keyframes only (the sweeps of --all-frames show none), with
thinner lines than the ground truth and a "<class> <score>" label; boxes scoring below the threshold are not drawn.
"""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.columns import to_numpy
from nuparquet.errors import UsageError
from nuparquet.frames.boxes import FramedCuboids
from nuparquet.geometry.cuboids import CuboidRows, Cuboids

DEFAULT_SCORE_THRESHOLD = 0.3
PREDICTED_RGB = (255, 0, 255)
TP_RGB = (40, 230, 40)
FP_RGB = (255, 45, 45)
FILTERED_RGB = (150, 150, 150)
STATUS_RGB = np.array([PREDICTED_RGB, TP_RGB, FP_RGB, FILTERED_RGB], dtype=np.uint8)
PREDICTED, TRUE_POSITIVE, FALSE_POSITIVE, FILTERED = 0, 1, 2, 3
# tracks: 20 well-separated colours (matplotlib's tab20, light and dark interleaved), one per tracking_id by a hash
# of the id that every process computes alike (Python's hash() of a string changes from run to run)
TRACK_PALETTE_RGB = np.array([
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75), (227, 119, 194),
    (127, 127, 127), (188, 189, 34), (23, 190, 207), (174, 199, 232), (255, 187, 120), (152, 223, 138),
    (255, 152, 150), (197, 176, 213), (196, 156, 148), (247, 182, 210), (199, 199, 199), (219, 219, 141),
    (158, 218, 229)], dtype=np.uint8)
HEAD_BYTES = 1 << 16  # how much of a results file is read to tell a tracking submission from a detection one


def track_rgb(tracking_ids: np.ndarray) -> np.ndarray:
    """(N, 3) uint8: the colour of each tracking_id (CRC-32 of its text into TRACK_PALETTE_RGB)."""
    ids = np.asarray(tracking_ids, dtype=object).astype(str)
    if not len(ids):
        return np.zeros((0, 3), np.uint8)
    unique, inverse = np.unique(ids, return_inverse=True)
    codes = np.array([zlib.crc32(text.encode()) for text in unique.tolist()], dtype=np.int64)  # per distinct id
    return TRACK_PALETTE_RGB[(codes % len(TRACK_PALETTE_RGB))[inverse.reshape(-1)]]


@dataclass(frozen=True)
class Predictions(CuboidRows):
    """The predicted boxes of one scene above the score threshold: `cuboids` (N,) global, and beside them
    sample_token, detection_name: (N,) str; score: (N,); status: (N,) int8 (PREDICTED, or TRUE_POSITIVE /
    FALSE_POSITIVE / FILTERED once evaluated)."""

    sample_token: np.ndarray
    detection_name: np.ndarray
    score: np.ndarray
    status: np.ndarray
    tracking_id: np.ndarray | None = None  # (N,) str for a tracking submission
    evaluated: bool = False  # from an evaluation directory (status colours)

    def colors_rgb(self, rows: np.ndarray) -> np.ndarray:
        if self.tracking_id is not None:
            return track_rgb(self.tracking_id[rows])
        return STATUS_RGB[self.status[rows]]

    def labels(self, rows: np.ndarray) -> list[str]:
        texts = [f"{name} {score:.2f}" for name, score in zip(self.detection_name[rows].tolist(),
                                                              self.score[rows].tolist())]
        if self.tracking_id is not None:
            texts = [f"{str(t)[:6]} {text}" for t, text in zip(self.tracking_id[rows].tolist(), texts)]
        return texts

    def legend(self) -> list[tuple[str, object]]:
        """(name, RGB or [RGB, ...]) entries saying what the colours of these predictions (thin lines) and of the
        ground truth beside them (thick lines) mean."""
        from nuparquet.rendering.palette import category_rgb

        truth = ("ground truth: category colours",
                 [category_rgb(name) for name in ("vehicle.car", "vehicle.truck", "human.pedestrian.adult",
                                                  "vehicle.bicycle")])
        if self.tracking_id is not None:
            return [("predicted track: one colour per id", [tuple(c) for c in TRACK_PALETTE_RGB[:6].tolist()]),
                    truth]
        if self.evaluated:
            return [("prediction, true positive", TP_RGB), ("prediction, false positive", FP_RGB),
                    ("prediction left out by a filter", FILTERED_RGB), truth]
        return [("prediction", PREDICTED_RGB), truth]


def load_predictions(source: str | Path, dataset, scene: str, score_threshold: float = DEFAULT_SCORE_THRESHOLD
                     ) -> Predictions:
    """The predictions of `scene` scoring at least `score_threshold`, from a results.json or an eval directory."""
    source = Path(source)
    if source.is_dir():
        return _from_evaluation(source, scene, score_threshold)
    if not source.is_file():
        raise UsageError(f"--predictions {source}: no such file or directory")
    return _from_submission(source, dataset, scene, score_threshold)


def is_tracking_submission(path: Path) -> bool:
    """The file's boxes carry a "tracking_id" (read from its first 64 KiB: a box comes early in any submission)."""
    with open(path, "rb") as f:
        return b'"tracking_id"' in f.read(HEAD_BYTES)


def _from_submission(path: Path, dataset, scene: str, score_threshold: float) -> Predictions:
    from nuparquet.evaluation.submission import DETECTION_FIELDS, TRACKING_FIELDS, read_boxes

    tracking = is_tracking_submission(path)
    fields = TRACKING_FIELDS if tracking else DETECTION_FIELDS
    if tracking:
        from nuparquet.evaluation.classes import TRACKING_NAMES as names
    else:
        from nuparquet.evaluation.classes import DETECTION_NAMES as names
    submission = read_boxes(path, fields, class_names=names)
    samples = set(dataset.scan("tables/sample").join(
        dataset.scan("scenes").filter(pl.col("name") == scene).select(pl.col("token").alias("scene_token")),
        on="scene_token", how="semi").select("token").collect()["token"].to_list())
    box_sample = submission.sample_tokens[submission.box_sample] if len(submission) else np.zeros(0, object)
    in_scene = np.isin(box_sample, np.array(sorted(samples), dtype=object))
    keep = in_scene & (submission.score >= score_threshold)
    return Predictions(cuboids=submission.cuboids.take(keep), sample_token=box_sample[keep],
                       detection_name=submission.class_name[keep], score=submission.score[keep],
                       status=np.full(int(keep.sum()), PREDICTED, dtype=np.int8),
                       tracking_id=submission.labels["tracking_id"][keep] if tracking else None)


def _from_evaluation(folder: Path, scene: str, score_threshold: float) -> Predictions:
    from nuparquet.evaluation.tables import threshold_suffix

    files = sorted((folder / "predictions").glob("*.parquet"))
    summary = folder / "metrics_summary.json"
    if not files and (folder / "predicted_tracks").is_dir():
        raise UsageError(f"--predictions {folder}: a tracking evaluation; give its submission (the tracking "
                         "results JSON) to draw each track in its colour")
    if not files or not summary.is_file():
        raise UsageError(f"--predictions {folder}: a directory, but not one written by `nuparquet eval` "
                         "(no predictions/*.parquet and metrics_summary.json)")
    tp_column = f"matched_gt_{threshold_suffix(json.loads(summary.read_text())['cfg']['dist_th_tp'])}"
    rows = (pl.scan_parquet(files).filter((pl.col("scene_name") == scene)
                                          & (pl.col("detection_score") >= score_threshold))
            .select("sample_token", "detection_name", "translation", "size", "rotation", "detection_score",
                    "evaluated", tp_column).collect())
    status = np.where(~rows["evaluated"].to_numpy(), FILTERED,
                      np.where(rows[tp_column].is_not_null().to_numpy(), TRUE_POSITIVE, FALSE_POSITIVE))
    return Predictions(cuboids=Cuboids(to_numpy(rows["translation"], (3,), writable=True),
                                       to_numpy(rows["size"], (3,), writable=True),
                                       to_numpy(rows["rotation"], (4,), writable=True)),
                       sample_token=rows["sample_token"].to_numpy().astype(object),
                       detection_name=rows["detection_name"].to_numpy().astype(object),
                       score=rows["detection_score"].to_numpy(), status=status.astype(np.int8), evaluated=True)


def prediction_boxes(frames: pl.DataFrame, predictions: Predictions) -> tuple[FramedCuboids, np.ndarray]:
    """The predictions on each keyframe of `frames` (rows with token, sample_token, is_key_frame), placed on the
    frames (frame_index = row of `frames`, source_index = the prediction's row), and (M,) the prediction row of
    each."""
    keyframe = frames["is_key_frame"].to_numpy()
    frame_sample = frames["sample_token"].to_numpy().astype(object)
    order = np.argsort(predictions.sample_token, kind="stable")
    sorted_samples = predictions.sample_token[order]
    first = np.searchsorted(sorted_samples, frame_sample, "left")
    count = np.where(keyframe, np.searchsorted(sorted_samples, frame_sample, "right") - first, 0)
    frame = np.repeat(np.arange(len(frame_sample)), count)
    rows = order[np.repeat(first, count) + np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)]
    boxes = FramedCuboids(cuboids=predictions.cuboids.take(rows), frame_index=frame.astype(np.int64),
                          source_index=rows.astype(np.int64), interpolated=np.zeros(len(rows), dtype=bool))
    return boxes, rows


def prediction_style(style):
    """The camera `DrawStyle` of predicted boxes: thinner lines than the ground truth's, smaller labels."""
    from nuparquet.rendering.overlay import DrawStyle

    return DrawStyle(tuple(max(1, w // 2) for w in style.widths), style.font_scale * 0.85, style.point_size_px)
