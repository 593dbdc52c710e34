"""The tracking evaluation's settings: the devkit's `TrackingConfig`, by name (`tracking_nips_2019`, the one of the
nuScenes tracking challenge) or from a JSON file in the devkit's format (`--config-file`).

Values keep the types the JSON gives them: the devkit writes its configuration back into metrics_summary.json
as read, and a worst value written `20` fills metrics_details.json with integers where `20.0` gives floats.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from nuparquet.errors import UsageError
from nuparquet.evaluation.classes import TRACKING_NAMES
from nuparquet.evaluation.config import _is_number

NAMED_CONFIGS = ("tracking_nips_2019",)
DEFAULT_CONFIG = "tracking_nips_2019"
_FIELDS = ("tracking_names", "pretty_tracking_names", "tracking_colors", "class_range", "dist_fcn", "dist_th_tp",
           "min_recall", "max_boxes_per_sample", "metric_worst", "num_thresholds")
# devkit constants.py: the metrics of the files, in its order; which are averaged over recall thresholds
AMOT_METRICS = ("amota", "amotp")
INTERNAL_METRICS = ("recall", "motar", "gt")
LEGACY_METRICS = ("mota", "motp", "mt", "ml", "faf", "tp", "fp", "fn", "ids", "frag", "tid", "lgd")
TRACKING_METRICS = (*AMOT_METRICS, *INTERNAL_METRICS, *LEGACY_METRICS)
AVERAGED_FROM = {"amota": "motar", "amotp": "motp"}  # devkit AVG_METRIC_MAP
SUMMED_METRICS = ("mt", "ml", "tp", "fp", "fn", "ids", "frag")  # over classes; the others are means


@dataclass(frozen=True)
class TrackingConfig:
    """The devkit's TrackingConfig. tracking_names: the classes a submission may name; class_range: {class: metres};
    dist_th_tp: the centre-distance threshold of a match (metres); min_recall: the lowest recall threshold;
    max_boxes_per_sample; metric_worst: {metric: the value of an unachieved recall threshold}; num_thresholds:
    the recall thresholds between min_recall and 1; pretty_tracking_names, tracking_colors: the plots' labels."""

    tracking_names: tuple
    pretty_tracking_names: dict
    tracking_colors: dict
    class_range: dict
    dist_fcn: str
    dist_th_tp: float
    min_recall: float
    max_boxes_per_sample: int
    metric_worst: dict
    num_thresholds: int

    named: ClassVar[tuple[str, ...]] = NAMED_CONFIGS
    default: ClassVar[str] = DEFAULT_CONFIG

    @property
    def class_names(self) -> tuple[str, ...]:
        """The evaluated classes in the devkit's order: sorted (`TrackingConfig.class_names`)."""
        return tuple(sorted(self.class_range))

    def serialize(self) -> dict:
        """The devkit's `TrackingConfig.serialize()` (the "cfg" of metrics_summary.json)."""
        return {"tracking_names": list(self.tracking_names), "pretty_tracking_names": dict(self.pretty_tracking_names),
                "tracking_colors": dict(self.tracking_colors), "class_range": dict(self.class_range),
                "dist_fcn": self.dist_fcn, "dist_th_tp": self.dist_th_tp, "min_recall": self.min_recall,
                "max_boxes_per_sample": self.max_boxes_per_sample, "metric_worst": dict(self.metric_worst),
                "num_thresholds": self.num_thresholds}

    @classmethod
    def from_dict(cls, content, where: str = "config") -> TrackingConfig:
        """Check `content` (a parsed devkit tracking config) and build the config; UsageError naming what is wrong."""
        if not isinstance(content, dict):
            raise UsageError(f"{where}: expected a JSON object with {', '.join(_FIELDS)}")
        missing = [name for name in _FIELDS if name not in content]
        if missing:
            raise UsageError(f"{where}: missing {', '.join(missing)}")
        names = content["tracking_names"]
        if not isinstance(names, list) or set(names) != set(TRACKING_NAMES) or len(names) != len(TRACKING_NAMES):
            raise UsageError(f"{where}: tracking_names must list each of {', '.join(TRACKING_NAMES)} once (the "
                             f"devkit's tracking classes), got {names!r}")
        for field in ("class_range", "pretty_tracking_names", "tracking_colors"):
            value = content[field]
            if not isinstance(value, dict) or set(value) != set(TRACKING_NAMES):
                raise UsageError(f"{where}: {field} must give a value for each of {', '.join(TRACKING_NAMES)} and "
                                 f"nothing else, got {sorted(value) if isinstance(value, dict) else value!r}")
        for name, value in content["class_range"].items():
            if not _is_number(value) or not value > 0:
                raise UsageError(f"{where}: class_range[{name!r}] must be a positive number of metres, got {value!r}")
        if content["dist_fcn"] != "center_distance":
            raise UsageError(f"{where}: dist_fcn must be center_distance (the devkit's only tracking distance), "
                             f"got {content['dist_fcn']!r}")
        if not _is_number(content["dist_th_tp"]) or not content["dist_th_tp"] > 0:
            raise UsageError(f"{where}: dist_th_tp must be a positive number of metres, got {content['dist_th_tp']!r}")
        if not _is_number(content["min_recall"]) or not 0 <= content["min_recall"] <= 1:
            raise UsageError(f"{where}: min_recall must be in [0, 1], got {content['min_recall']!r}")
        for field in ("max_boxes_per_sample", "num_thresholds"):
            value = content[field]
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise UsageError(f"{where}: {field} must be a positive integer, got {value!r}")
        worst = content["metric_worst"]
        if not isinstance(worst, dict) or set(worst) != set(TRACKING_METRICS):
            raise UsageError(f"{where}: metric_worst must give a value for each of {', '.join(TRACKING_METRICS)}, "
                             f"got {sorted(worst) if isinstance(worst, dict) else worst!r}")
        for name, value in worst.items():
            if not _is_number(value):
                raise UsageError(f"{where}: metric_worst[{name!r}] must be a number, got {value!r}")
        return cls(tracking_names=tuple(names), pretty_tracking_names=dict(content["pretty_tracking_names"]),
                   tracking_colors=dict(content["tracking_colors"]), class_range=dict(content["class_range"]),
                   dist_fcn=content["dist_fcn"], dist_th_tp=content["dist_th_tp"], min_recall=content["min_recall"],
                   max_boxes_per_sample=content["max_boxes_per_sample"], metric_worst=dict(worst),
                   num_thresholds=content["num_thresholds"])


def resolve_tracking_config(config=None, config_file=None) -> TrackingConfig:
    """The configuration asked for: a TrackingConfig as given, `config_file`, else the named `config`."""
    from nuparquet.evaluation.config import resolve_config

    return resolve_config(config, config_file, TrackingConfig)
