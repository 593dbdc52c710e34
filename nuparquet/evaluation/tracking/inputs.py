"""What one tracking evaluation reads, checked and filtered: the submission (the detection reader with the tracking
fields, and no tracking_id twice in a sample), the ground truth of the split (the detection loader with the tracking
classes), the devkit's filters (class range, points, bike racks, the detection evaluation's), the samples laid out
by scene; and the evaluation of chosen rows of it (the whole, or a slice)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.errors import InputError
from nuparquet.evaluation import filters
from nuparquet.evaluation.boxes import Boxes
from nuparquet.evaluation.classes import CATEGORY_TO_TRACKING, CYCLE_CLASSES
from nuparquet.evaluation.ground_truth import GroundTruth, load_ground_truth
from nuparquet.evaluation.splits import is_predefined
from nuparquet.evaluation.submission import (
    MAX_LISTED, TRACKING_FIELDS, SubmittedBoxes, check_samples, read_boxes, restricted_to_split,
)
from nuparquet.evaluation.tracking.config import TrackingConfig
from nuparquet.evaluation.tracking.scoring import TrackingEvaluation, score_tracks
from nuparquet.evaluation.tracking.tracks import Timeline, TrackedBoxes, build_tracks
from nuparquet.geometry.cuboids import Cuboids


@dataclass(frozen=True)
class Inputs:
    """The filtered boxes of one evaluation, before tracking: rows of the ground truth and of the submission
    that pass the devkit's filters, and everything needed to make tracks of them."""

    gt: GroundTruth
    sub: SubmittedBoxes
    timeline: Timeline
    gt_kept: np.ndarray
    pred_kept: np.ndarray
    pred_sample: np.ndarray
    pred_class: np.ndarray
    gt_distance_m: np.ndarray
    pred_distance_m: np.ndarray
    gt_reason: np.ndarray
    pred_reason: np.ndarray


def check_track_ids(sub: SubmittedBoxes, path) -> None:
    """A tracking_id given to two boxes of one sample is refused (the devkit would match one of them by list
    position and give both its track's score), naming the sample and the boxes."""
    ids = sub.labels["tracking_id"]
    if not len(ids):
        return
    _, code = np.unique(ids.astype(str), return_inverse=True)
    key = sub.box_sample * (int(code.max()) + 1) + code.reshape(-1)
    order = np.argsort(key, kind="stable")
    repeated = order[1:][key[order][1:] == key[order][:-1]]
    if len(repeated):
        first = {int(k): int(r) for k, r in zip(key[order][::-1], order[::-1])}
        lines = [f"sample {sub.sample_tokens[sub.box_sample[r]]} box {int(sub.box_index[r])}: tracking_id "
                 f"{ids[r]!r} already given to box {int(sub.box_index[first[int(key[r])]])} of the sample"
                 for r in repeated[:MAX_LISTED]]
        more = f"\n  ... and {len(repeated) - MAX_LISTED} more" if len(repeated) > MAX_LISTED else ""
        raise InputError(f"{path}: {len(repeated)} problem(s) in the submission:\n  " + "\n  ".join(lines) + more)


def prepare(ds, results, config: TrackingConfig, split: str, *, annotation_columns=(), scene_columns=()) -> Inputs:
    """Read and check the submission, load the ground truth of `split`, apply the devkit's filters."""
    sub = read_boxes(results, TRACKING_FIELDS, max_boxes_per_sample=config.max_boxes_per_sample,
                     class_names=config.tracking_names)
    check_track_ids(sub, results)
    names = config.class_names
    gt = load_ground_truth(ds, split, names, annotation_columns=["instance_token", *annotation_columns],
                           scene_columns=scene_columns, category_map=CATEGORY_TO_TRACKING, one_attribute=False)
    custom = not is_predefined(split)
    check_samples(sub, gt.samples.token.tolist(), split=split, path=results, allow_extra=custom)
    if custom:
        sub = restricted_to_split(sub, gt.samples.token)
    sample_of = {token: i for i, token in enumerate(gt.samples.token.tolist())}
    sample_index = np.array([sample_of[t] for t in sub.sample_tokens.tolist()], dtype=np.int64)
    pred_sample = sample_index[sub.box_sample] if len(sub) else np.zeros(0, np.int64)
    class_of = {name: i for i, name in enumerate(names)}
    class_names, inverse = np.unique(sub.class_name.astype(str), return_inverse=True)
    pred_class = (np.array([class_of[n] for n in class_names.tolist()], np.int64)[inverse.reshape(-1)]
                  if len(sub) else np.zeros(0, np.int64))
    n = len(sub)
    pred = Boxes(cuboids=sub.cuboids, sample_index=pred_sample, class_index=pred_class, velocity_mps=sub.velocity_mps,
                 attribute=np.full(n, "", object), score=sub.score, num_pts=sub.num_pts)
    class_range = np.array([float(config.class_range[name]) for name in names])
    cycle = np.isin(np.array(names), CYCLE_CLASSES)
    gt_distance = filters.ego_distances_m(gt.boxes, gt.samples.ego_xyz_m)
    pred_distance = filters.ego_distances_m(pred, gt.samples.ego_xyz_m)
    gt_reason = filters.filter_reasons(gt.boxes, gt_distance, class_range, cycle, gt.racks)
    pred_reason = filters.filter_reasons(pred, pred_distance, class_range, cycle, gt.racks)
    scene_of = {token: i for i, token in enumerate(gt.scenes["token"].to_list())}
    scene_index = np.array([scene_of[t] for t in gt.samples.scene_token.tolist()], dtype=np.int64)
    timeline = Timeline.of(scene_index, gt.samples.timestamp_us, gt.scenes.height)
    return Inputs(gt=gt, sub=sub, timeline=timeline, gt_kept=np.flatnonzero(gt_reason == filters.KEPT),
                  pred_kept=np.flatnonzero(pred_reason == filters.KEPT), pred_sample=pred_sample,
                  pred_class=pred_class, gt_distance_m=gt_distance, pred_distance_m=pred_distance,
                  gt_reason=gt_reason, pred_reason=pred_reason)


def tracks_of(inputs: Inputs, gt_rows: np.ndarray, pred_rows: np.ndarray) -> tuple[TrackedBoxes, TrackedBoxes]:
    """The tracks (interpolated) of the given rows of the ground truth and the submission (kept rows, in order)."""
    gt, sub = inputs.gt, inputs.sub
    boxes = gt.boxes
    gt_tracks = build_tracks(
        Cuboids(boxes.translation_m[gt_rows], boxes.size_wlh_m[gt_rows], boxes.rotation_wxyz[gt_rows]),
        boxes.sample_index[gt_rows], gt.annotations["instance_token"].to_numpy().astype(object)[gt_rows],
        boxes.class_index[gt_rows], np.full(len(gt_rows), -1.0), inputs.timeline, average_scores=False)
    pred_tracks = build_tracks(
        Cuboids(sub.translation_m[pred_rows], sub.size_wlh_m[pred_rows], sub.rotation_wxyz[pred_rows]),
        inputs.pred_sample[pred_rows], sub.labels["tracking_id"][pred_rows], inputs.pred_class[pred_rows],
        sub.score[pred_rows], inputs.timeline, average_scores=True)
    return gt_tracks, pred_tracks


def evaluate_rows(inputs: Inputs, gt_rows: np.ndarray, pred_rows: np.ndarray, config: TrackingConfig
                  ) -> tuple[TrackingEvaluation, TrackedBoxes, TrackedBoxes]:
    gt_tracks, pred_tracks = tracks_of(inputs, gt_rows, pred_rows)
    evaluation = score_tracks(gt_tracks, pred_tracks, config, len(inputs.gt.samples), inputs.timeline.max_positions)
    return evaluation, gt_tracks, pred_tracks
