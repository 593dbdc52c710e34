"""Slices: the same metrics on a part of the evaluation (`--by distance|visibility|attribute|location|night|rain|
scene` or any column of `annotations` or `scenes`).

A slice is defined as a filter of both inputs, applied after the devkit's own filters (class range, points,
bike racks); the slice is then evaluated exactly as a whole evaluation is (matching, curves, AP, TP errors,
NDS), so its numbers are those the devkit gives for the correspondingly filtered ground truth and predictions.

How each box is placed in a slice:
- a ground-truth box by its own value: its xy distance to the ego vehicle (`distance`, in `--bins` metres,
  default 0-10-20-30-40-50), its visibility bin (`visibility`: `visibility_name`, "none" without one), its
  attribute (`attribute`, "none" without one), its scene's log location (`location`), whether its scene's
  description mentions night (`night`: night / day) or rain (`rain`: rain / dry), its scene (`scene`), or the
  value of the column asked for (numeric columns by `--bins` edges, or by value when they take at most
  MAX_VALUES values);
- a prediction by its own value where it has one: its distance to the ego vehicle, its sample's scene (location,
  night, rain, scene, any `scenes` column, and the annotation columns that describe the sample: scene_name,
  scene_token, log_location, sample_token, timestamp);
- otherwise (visibility, attribute and other annotation columns: properties a prediction does not have) by
  the ground-truth box it matched in the whole evaluation at the TP threshold (`dist_th_tp`, 2 m); a prediction
  that matched nothing there is a false positive of every slice (it cannot be told which it belongs to; this
  never flatters a slice: its precision and AP are lower bounds, its recall exact), except for `attribute`,
  where an unmatched prediction goes to the slice of the attribute it predicted.

Ranges are half-open, [low, high) metres; boxes beyond the last edge form a last slice "<edge>m+".
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl

from nuparquet.errors import UsageError

NAMED = ("distance", "visibility", "attribute", "location", "night", "rain", "scene")
DEFAULT_DISTANCE_BINS_M = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0)
MAX_VALUES = 20  # a numeric column taking more values than this needs --bins
EVERY_SLICE = "*"  # the value of a prediction charged to every slice
SAMPLE_COLUMNS = ("scene_name", "scene_token", "log_location", "sample_token", "timestamp")  # a prediction has these
_NIGHT = re.compile(r"\bnight", re.IGNORECASE)
_RAIN = re.compile(r"\brain", re.IGNORECASE)


@dataclass(frozen=True)
class Dimension:
    """One `--by`: the slice label of every evaluated ground-truth box and prediction, and the labels in order.

    gt_label: (G,) object; pred_label: (P,) object, EVERY_SLICE for a prediction of every slice."""

    name: str
    labels: tuple[str, ...]
    gt_label: np.ndarray
    pred_label: np.ndarray

    def masks(self, label: str) -> tuple[np.ndarray, np.ndarray]:
        """(G,) and (P,) bool: the boxes of slice `label`."""
        return self.gt_label == label, (self.pred_label == label) | (self.pred_label == EVERY_SLICE)


def parse_bins(bins: Sequence) -> tuple[float, ...]:
    """--bins edges: at least two increasing numbers."""
    try:
        edges = tuple(float(b) for b in bins)
    except (TypeError, ValueError):
        raise UsageError(f"--bins must be numbers (edges, e.g. 0,10,20,30), got {','.join(map(str, bins))}") from None
    if len(edges) < 2 or any(b <= a for a, b in zip(edges, edges[1:])) or not all(np.isfinite(edges)):
        raise UsageError(f"--bins needs at least two increasing edges, got {','.join(map(str, bins))}")
    return edges


def needed_columns(by: Sequence[str], annotation_columns: Sequence[str], scene_columns: Sequence[str]
                   ) -> tuple[list[str], list[str]]:
    """The extra annotation and scene columns the dimensions `by` read; UsageError for an unknown name."""
    annotations, scenes = [], []
    for name in by:
        if name in NAMED:
            if name == "visibility":
                annotations.append("visibility_name")
        elif name in scene_columns or name in SAMPLE_COLUMNS:
            if name in scene_columns and name not in SAMPLE_COLUMNS:
                scenes.append(name)
        elif name in annotation_columns:
            annotations.append(name)
        else:
            raise UsageError(f"--by {name}: not a slice ({', '.join(NAMED)}) nor a column of annotations or scenes "
                             f"(annotations: {', '.join(annotation_columns)}; scenes: {', '.join(scene_columns)})")
    return list(dict.fromkeys(annotations)), list(dict.fromkeys(scenes))


def bin_labels(values: np.ndarray, edges: tuple[float, ...], unit: str) -> tuple[np.ndarray, list[str]]:
    """(N,) object label of each value in the half-open bins [low, high) of `edges` ("<last>unit+" beyond the last
    edge, None below the first or for NaN), and the labels in order."""
    names = [f"{a:g}-{b:g}{unit}" for a, b in zip(edges, edges[1:])] + [f"{edges[-1]:g}{unit}+"]
    index = np.searchsorted(np.asarray(edges), values, side="right") - 1  # [low, high)
    labels = np.full(len(values), None, dtype=object)
    inside = (index >= 0) & ~np.isnan(values)
    labels[inside] = np.array(names, dtype=object)[np.minimum(index[inside], len(names) - 1)]
    return labels, names


def _value_labels(values: pl.Series, name: str, bins: tuple[float, ...] | None) -> tuple[np.ndarray, list[str] | None]:
    """Labels of a column's values: by bins for numbers given --bins, else by value (numbers with few values)."""
    if values.dtype.is_numeric() and not values.dtype == pl.Boolean:
        if bins is not None:
            return bin_labels(values.cast(pl.Float64).fill_null(np.nan).to_numpy(), bins, "")
        distinct = values.drop_nulls().n_unique()
        if distinct > MAX_VALUES:
            raise UsageError(f"--by {name}: {distinct} distinct values; give --bins edges to group them")
    text = values.cast(pl.String).fill_null("none")
    return text.to_numpy().astype(object), None


SCENE_NAMED = ("location", "night", "rain", "scene")  # the named slices a scene decides


def scene_labels(name: str, scenes: pl.DataFrame, bins: tuple[float, ...] | None
                 ) -> tuple[np.ndarray, list[str] | None]:
    """(R,) object label of each row of `scenes` (one row per sample or frame, with its scene's `name`,
    `description`, `log_location` and the columns asked for) in the scene-decided dimension `name`, and the
    labels' order where it is not alphabetical (None)."""
    if name == "location":
        return scenes["log_location"].fill_null("none").to_numpy().astype(object), None
    if name in ("night", "rain"):
        pattern, yes, no = (_NIGHT, "night", "day") if name == "night" else (_RAIN, "rain", "dry")
        found = np.array([bool(pattern.search(d or "")) for d in scenes["description"].to_list()], bool)
        return np.where(found, yes, no).astype(object), [no, yes]
    if name == "scene":
        return scenes["name"].to_numpy().astype(object), None
    return _value_labels(scenes[name], name, bins)


def dimension(name: str, *, gt_ego_distance_m: np.ndarray, pred_ego_distance_m: np.ndarray,
              gt_annotations: pl.DataFrame, gt_attribute: np.ndarray, pred_attribute: np.ndarray,
              gt_sample: np.ndarray, pred_sample: np.ndarray, sample_scene: pl.DataFrame,
              pred_matched_gt: np.ndarray, bins: tuple[float, ...] | None) -> Dimension:
    """The slice labels of dimension `name` (see the module docstring).

    gt_*: the evaluated ground-truth boxes (annotations: one row each, with the columns `needed_columns`
    asked for); pred_*: the evaluated predictions; *_sample: (N,) sample index of each box; sample_scene: one row
    per sample (its scene's columns and sample_token, timestamp); pred_matched_gt: (P,) row of the evaluated
    ground truth each prediction matched at the TP threshold, -1 for none.
    """
    order = None
    if name == "distance":
        edges = bins or DEFAULT_DISTANCE_BINS_M
        gt_label, order = bin_labels(gt_ego_distance_m, edges, "m")
        pred_label, _ = bin_labels(pred_ego_distance_m, edges, "m")
    elif name in SCENE_NAMED or name in sample_scene.columns:
        per_sample, order = scene_labels(name, sample_scene, bins)
        gt_label, pred_label = per_sample[gt_sample], per_sample[pred_sample]
    else:
        if name == "visibility":
            gt_label = gt_annotations["visibility_name"].fill_null("none").to_numpy().astype(object)
        elif name == "attribute":
            gt_label = np.where(gt_attribute == "", "none", gt_attribute).astype(object)
        else:
            gt_label, order = _value_labels(gt_annotations[name], name, bins)
        matched = pred_matched_gt >= 0
        pred_label = np.full(len(pred_matched_gt), EVERY_SLICE, dtype=object)
        pred_label[matched] = gt_label[pred_matched_gt[matched]]
        if name == "attribute":
            own = np.where(pred_attribute == "", "none", pred_attribute).astype(object)
            pred_label[~matched] = own[~matched]
    present = set(gt_label[gt_label != None].tolist()) | set(  # noqa: E711 - object arrays
        pred_label[(pred_label != None) & (pred_label != EVERY_SLICE)].tolist())  # noqa: E711
    labels = [label for label in order if label in present] if order is not None else sorted(present)
    return Dimension(name=name, labels=tuple(labels), gt_label=gt_label, pred_label=pred_label)
