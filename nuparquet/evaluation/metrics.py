"""From matches to the nuScenes metrics, with the devkit's arithmetic (`accumulate`'s interpolation,
`calc_ap`, `calc_tp`, `DetectionMetrics`): the same numpy calls on the same arrays, so the numbers agree to
the last bit except the orientation error, whose yaw comes from the vectorised rotation matrices
(`quaternions.heading_from_quaternions`, equal to pyquaternion's to rounding).

The TP errors of a match (devkit `center_distance`, `velocity_l2`, `scale_iou`, `yaw_diff`, `attr_acc`) are
computed for all matches at once (`match_errors`); `metric_data` then builds, per class and threshold, the
101-point curves the devkit's `DetectionMetricData` holds; `summarize` the metrics_summary.json contents.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.evaluation.boxes import Boxes
from nuparquet.evaluation.classes import NUSCENES, TP_METRICS, Taxonomy
from nuparquet.evaluation.config import DetectionConfig
from nuparquet.evaluation.matching import Matches
from nuparquet.geometry.dots import rowwise_norm
from nuparquet.geometry.quaternions import heading_from_quaternions

NELEM = 101  # recall points of the curves (devkit DetectionMetricData.nelem)


@dataclass(frozen=True)
class MetricData:
    """The devkit's `DetectionMetricData`: (101,) arrays over recall 0..1."""

    recall: np.ndarray
    precision: np.ndarray
    confidence: np.ndarray
    trans_err: np.ndarray
    vel_err: np.ndarray
    scale_err: np.ndarray
    orient_err: np.ndarray
    attr_err: np.ndarray

    @classmethod
    def no_predictions(cls) -> MetricData:
        return cls(recall=np.linspace(0, 1, NELEM), precision=np.zeros(NELEM), confidence=np.zeros(NELEM),
                   trans_err=np.ones(NELEM), vel_err=np.ones(NELEM), scale_err=np.ones(NELEM),
                   orient_err=np.ones(NELEM), attr_err=np.ones(NELEM))

    @property
    def max_recall_ind(self) -> int:
        """Index of the last non-zero confidence (the highest recall reached), 0 without any."""
        non_zero = np.nonzero(self.confidence)[0]
        return int(non_zero[-1]) if len(non_zero) else 0

    @property
    def max_recall(self) -> float:
        return float(self.recall[self.max_recall_ind])

    def serialize(self) -> dict:
        return {name: getattr(self, name).tolist() for name in
                ("recall", "precision", "confidence", "trans_err", "vel_err", "scale_err", "orient_err", "attr_err")}


def cummean(x: np.ndarray) -> np.ndarray:
    """The devkit's NaN-aware cumulative mean (all NaN, or empty: ones)."""
    if np.isnan(x).all():  # the devkit's sum(np.isnan(x)) == len(x), without a Python loop
        return np.ones(len(x))
    sum_vals = np.nancumsum(x.astype(float))
    count_vals = np.cumsum(~np.isnan(x))
    return np.divide(sum_vals, count_vals, out=np.zeros_like(sum_vals), where=count_vals != 0)


def match_errors(gt: Boxes, pred: Boxes, gt_rows: np.ndarray, pred_rows: np.ndarray, distance_m: np.ndarray,
                 class_names: tuple[str, ...], taxonomy: Taxonomy = NUSCENES) -> dict[str, np.ndarray]:
    """The TP errors of matched pairs (K,), as the devkit computes them per match.

    trans_err: the centre distance; vel_err: xy velocity difference norm (NaN if either is NaN); scale_err:
    1 - IoU of the boxes aligned at one centre and heading; orient_err: |yaw difference| wrapped to the class's
    period (`taxonomy.period_rad`: pi for barriers, and TruckScenes' traffic signs); attr_err: 0 / 1, NaN where the ground truth has no attribute.
    """
    g, p = gt.take(gt_rows), pred.take(pred_rows)
    vel_err = rowwise_norm(p.velocity_mps - g.velocity_mps)  # the devkit's velocity_l2: np.linalg.norm
    sa, sr = g.size_wlh_m, p.size_wlh_m
    mins = np.minimum(sa, sr)
    volume_annotation = sa[:, 0] * sa[:, 1] * sa[:, 2]
    volume_result = sr[:, 0] * sr[:, 1] * sr[:, 2]
    intersection = mins[:, 0] * mins[:, 1] * mins[:, 2]
    iou = intersection / (volume_annotation + volume_result - intersection)
    period = np.array([taxonomy.period_rad(name) for name in class_names])[p.class_index]
    diff = np.mod(heading_from_quaternions(g.rotation_wxyz) - heading_from_quaternions(p.rotation_wxyz)
                  + period / 2, period) - period / 2
    diff = np.where(diff > np.pi, diff - 2 * np.pi, diff)
    with np.errstate(invalid="ignore"):
        attr_err = np.where(g.attribute == "", np.nan, 1.0 - (g.attribute == p.attribute).astype(float))
    return {"trans_err": np.asarray(distance_m, dtype=np.float64), "vel_err": vel_err, "scale_err": 1 - iou,
            "orient_err": np.abs(diff), "attr_err": attr_err}


def accumulate(num_gt: int, scores: np.ndarray, is_tp: np.ndarray, errors: dict[str, np.ndarray]) -> MetricData:
    """One class at one threshold: the devkit's `accumulate` after its matching loop.

    scores, is_tp: (P,) the class's predictions in processing order; errors: (K,) TP errors of its matches, in
    the same order (K = is_tp.sum()).
    """
    if num_gt == 0 or not is_tp.any():
        return MetricData.no_predictions()
    tp = np.cumsum(is_tp.astype(np.int64)).astype(float)
    fp = np.cumsum((~is_tp).astype(np.int64)).astype(float)
    conf = np.asarray(scores, dtype=np.float64)
    prec = tp / (fp + tp)
    rec = tp / float(num_gt)
    rec_interp = np.linspace(0, 1, NELEM)
    prec = np.interp(rec_interp, rec, prec, right=0)
    conf = np.interp(rec_interp, rec, conf, right=0)
    match_conf = scores[is_tp][::-1]
    curves = {key: np.interp(conf[::-1], match_conf, cummean(np.asarray(errors[key]))[::-1])[::-1]
              for key in TP_METRICS}
    return MetricData(recall=rec_interp, precision=prec, confidence=conf, **curves)


def calc_ap(md: MetricData, min_recall: float, min_precision: float) -> float:
    """The devkit's `calc_ap`: mean precision above min_recall, clipped at min_precision and rescaled."""
    prec = np.copy(md.precision)
    prec = prec[round(100 * min_recall) + 1:]
    prec -= min_precision
    prec[prec < 0] = 0
    return float(np.mean(prec)) / (1.0 - min_precision)


def calc_tp(md: MetricData, min_recall: float, metric_name: str) -> float:
    """The devkit's `calc_tp`: mean error from just above min_recall to the highest recall reached (1.0 when
    that is not above min_recall)."""
    first_ind = round(100 * min_recall) + 1
    last_ind = md.max_recall_ind
    if last_ind < first_ind:
        return 1.0
    return float(np.mean(getattr(md, metric_name)[first_ind: last_ind + 1]))


def metric_data(gt: Boxes, pred: Boxes, matches: Matches, config: DetectionConfig) -> dict[tuple, MetricData]:
    """{(class, threshold): MetricData} for every class of `config` and threshold, in the devkit's order."""
    class_names = config.class_names
    num_gt = np.bincount(gt.class_index, minlength=len(class_names))
    ordered_class = pred.class_index[matches.order]
    bounds = np.searchsorted(ordered_class, np.arange(len(class_names) + 1))
    result = {}
    for t, threshold in enumerate(matches.thresholds):
        matched = matches.gt[t]
        hit = np.flatnonzero(matched >= 0)
        errors = match_errors(gt, pred, matched[hit], hit, matches.distance_m[t, hit], class_names,
                              config.taxonomy)
        error_at = np.full(len(pred), -1, dtype=np.int64)
        error_at[hit] = np.arange(len(hit))
        for c, name in enumerate(class_names):
            rows = matches.order[bounds[c]:bounds[c + 1]]
            is_tp = matched[rows] >= 0
            picked = error_at[rows[is_tp]]
            md = accumulate(int(num_gt[c]), pred.score[rows], is_tp, {k: v[picked] for k, v in errors.items()})
            result[(name, threshold)] = md
    return {(name, threshold): result[(name, threshold)] for name in class_names for threshold in config.dist_ths}


@dataclass(frozen=True)
class DetectionMetrics:
    """The devkit's `DetectionMetrics`: AP per class and threshold, TP errors per class, and what follows."""

    config: DetectionConfig
    label_aps: dict  # {class: {threshold: ap}}
    label_tp_errors: dict  # {class: {metric: error}}
    eval_time: float | None = None

    @property
    def mean_dist_aps(self) -> dict:
        return {name: np.mean(list(aps.values())) for name, aps in self.label_aps.items()}

    @property
    def mean_ap(self) -> float:
        return float(np.mean(list(self.mean_dist_aps.values())))

    @property
    def tp_errors(self) -> dict:
        errors = {}
        for metric in TP_METRICS:
            class_errors = [self.label_tp_errors[name][metric] for name in self.config.class_names]
            with np.errstate(invalid="ignore"):
                errors[metric] = float(np.nanmean(class_errors)) if not np.isnan(class_errors).all() else np.nan
        return errors

    @property
    def tp_scores(self) -> dict:
        return {metric: max(0.0, 1.0 - error) for metric, error in self.tp_errors.items()}

    @property
    def nd_score(self) -> float:
        total = float(self.config.mean_ap_weight * self.mean_ap + np.sum(list(self.tp_scores.values())))
        return total / float(self.config.mean_ap_weight + len(self.tp_scores))

    def serialize(self) -> dict:
        """metrics_summary.json without "meta" (the devkit's `DetectionMetrics.serialize()`)."""
        return {"label_aps": self.label_aps, "mean_dist_aps": self.mean_dist_aps, "mean_ap": self.mean_ap,
                "label_tp_errors": self.label_tp_errors, "tp_errors": self.tp_errors, "tp_scores": self.tp_scores,
                "nd_score": self.nd_score, "eval_time": self.eval_time, "cfg": self.config.serialize()}


def detection_metrics(data: dict[tuple, MetricData], config: DetectionConfig,
                      eval_time: float | None = None) -> DetectionMetrics:
    """AP and TP errors from the curves, as the devkit's `DetectionEval.evaluate` step 2."""
    label_aps: dict = {}
    label_tp_errors: dict = {}
    for name in config.class_names:
        label_aps[name] = {threshold: calc_ap(data[(name, threshold)], config.min_recall, config.min_precision)
                           for threshold in config.dist_ths}
        md = data[(name, config.dist_th_tp)]
        undefined = config.taxonomy.undefined_tp_metrics.get(name, ())
        label_tp_errors[name] = {metric: (np.nan if metric in undefined
                                          else calc_tp(md, config.min_recall, metric)) for metric in TP_METRICS}
    return DetectionMetrics(config, label_aps, label_tp_errors, eval_time)


def serialize_details(data: dict[tuple, MetricData], tag: str | None = None) -> dict:
    """metrics_details.json: {"<class>:<threshold>": curves} (the devkit's `DetectionMetricDataList`).

    tag: TruckScenes' list, keyed (tag, class, threshold) but serialized as "<tag>:<class>", so each class's
    key is written once, in its first place, holding its last threshold's curves (truckscenes-devkit 1.2.0's
    file, kept as it is: the other thresholds' curves are in the predictions table's matches)."""
    if tag is not None:
        return {f"{tag}:{name}": md.serialize() for (name, _threshold), md in data.items()}
    return {f"{name}:{threshold}": md.serialize() for (name, threshold), md in data.items()}
