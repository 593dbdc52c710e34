"""The tracking metrics per slice (`by=`): each slice is a filter of the ground truth and the predictions applied
with the devkit's own filters, before the tracks are made (so a track leaving a distance bin and coming back is
interpolated across, as the devkit would do given those boxes), then evaluated as a whole evaluation is.

Boxes are placed in slices as in the detection evaluation (`nuparquet.evaluation.slices`): the ground truth by
its own value, a prediction by its own value where it has one (its distance, its sample's scene), else by the
ground-truth box it matched with every prediction kept (the accumulator's run without a threshold); a prediction
that matched nothing there is a false positive in every slice."""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.evaluation.slices import dimension
from nuparquet.evaluation.tracking.config import TrackingConfig
from nuparquet.evaluation.tracking.inputs import evaluate_rows

HEADLINE = ("amota", "amotp", "recall", "motar", "mota", "motp", "ids", "frag", "tid", "lgd")


def matched_ground_truth(inputs, evaluation, gt_tracks, pred_tracks) -> np.ndarray:
    """(P,) for each kept prediction, the kept ground-truth row it matched with every prediction kept (-1)."""
    out = np.full(len(inputs.pred_kept), -1, np.int64)
    for c in evaluation.classes.values():
        if c.every is None:
            continue
        matched = c.every.matched_pred[0]
        hit = np.flatnonzero(matched >= 0)
        gt_source = gt_tracks.source[c.gt_rows[hit]]
        pred_source = pred_tracks.source[c.pred_rows[matched[hit]]]
        real = (gt_source >= 0) & (pred_source >= 0)  # interpolated boxes belong to no slice of their own
        out[pred_source[real]] = gt_source[real]
    return out


def evaluate_slices(by, inputs, whole, gt_tracks, pred_tracks, config: TrackingConfig, bins, reporter, steps: int):
    """(slices table, {(by, slice): summary}, {(by, slice): details})."""
    gt, sub = inputs.gt, inputs.sub
    kept_gt, kept_pred = inputs.gt_kept, inputs.pred_kept
    samples = gt.samples
    sample_scene = (pl.DataFrame({"sample_token": samples.token, "scene_token": samples.scene_token,
                                  "scene_name": samples.scene_name, "timestamp": samples.timestamp_us},
                                 schema={"sample_token": pl.String, "scene_token": pl.String,
                                         "scene_name": pl.String, "timestamp": pl.Int64})
                    .join(gt.scenes, left_on="scene_token", right_on="token", how="left", maintain_order="left"))
    matched = matched_ground_truth(inputs, whole, gt_tracks, pred_tracks)
    empty = np.full(len(kept_pred), "", object)
    dimensions = [dimension(name, gt_ego_distance_m=inputs.gt_distance_m[kept_gt],
                            pred_ego_distance_m=inputs.pred_distance_m[kept_pred],
                            gt_annotations=gt.annotations[kept_gt], gt_attribute=gt.boxes.attribute[kept_gt],
                            pred_attribute=empty, gt_sample=gt.boxes.sample_index[kept_gt],
                            pred_sample=inputs.pred_sample[kept_pred], sample_scene=sample_scene,
                            pred_matched_gt=matched, bins=bins) for name in by]
    reporter.set_total(steps + sum(len(d.labels) for d in dimensions))
    rows, summaries, details = [], {}, {}
    for dim in dimensions:
        for label in dim.labels:
            gt_mask, pred_mask = dim.masks(label)
            evaluation, _, _ = evaluate_rows(inputs, kept_gt[gt_mask], kept_pred[pred_mask], config)
            summary = evaluation.summary(config, sub.meta)
            summaries[(dim.name, label)] = summary
            details[(dim.name, label)] = evaluation.details()
            rows.append({"by": dim.name, "slice": label, "num_gt": int(gt_mask.sum()),
                         "num_predictions": int(pred_mask.sum()), **{m: summary[m] for m in HEADLINE},
                         **{f"AMOTA_{name}": summary["label_metrics"]["amota"][name] for name in config.class_names}})
            reporter.advance(step=f"slice {dim.name} {label}")
    schema = {"by": pl.String, "slice": pl.String, "num_gt": pl.Int64, "num_predictions": pl.Int64,
              **{m: pl.Float64 for m in HEADLINE}, **{f"AMOTA_{name}": pl.Float64 for name in config.class_names}}
    return pl.DataFrame(rows, schema=schema), summaries, details
