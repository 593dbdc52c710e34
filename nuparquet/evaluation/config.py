"""The evaluation settings: the devkit's `DetectionConfig`, by name (`detection_cvpr_2019`, the one every
nuScenes paper uses; `detection_cvpr_2024`, truckscenes-devkit's for MAN TruckScenes) or from a JSON file in the
devkit's format (`--config-file`). Its classes decide the taxonomy (`classes.Taxonomy`) it evaluates.

Values keep the types the JSON gives them (a threshold written `1` stays an int), because the devkit's output
keys are built from them (`"car:1"` vs `"car:1.0"` in metrics_details.json).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import ClassVar

from nuparquet.errors import UsageError
from nuparquet.evaluation.classes import NUSCENES, TAXONOMIES, Taxonomy, taxonomy_of

NAMED_CONFIGS = ("detection_cvpr_2019", "detection_cvpr_2024")
DEFAULT_CONFIG = "detection_cvpr_2019"
# the configuration a dataset of each family is evaluated with unless one is named
FAMILY_CONFIGS = {"nuscenes": "detection_cvpr_2019", "truckscenes": "detection_cvpr_2024"}
DISTANCE_FUNCTIONS = ("center_distance",)
_FIELDS = ("class_range", "dist_fcn", "dist_ths", "dist_th_tp", "min_recall", "min_precision",
           "max_boxes_per_sample", "mean_ap_weight")


@dataclass(frozen=True)
class DetectionConfig:
    """class_range: {detection class: metres} (every class of the devkit, in the order results are reported);
    dist_fcn: "center_distance"; dist_ths: matching thresholds (metres, xy centre distance); dist_th_tp: the
    threshold the TP errors use (one of dist_ths); min_recall, min_precision: the AP and TP-error clips;
    max_boxes_per_sample: a submission's limit; mean_ap_weight: mAP's weight in NDS; taxonomy: the devkit
    vocabulary whose classes class_range names (not serialized: the classes say it)."""

    class_range: dict
    dist_fcn: str
    dist_ths: tuple
    dist_th_tp: float
    min_recall: float
    min_precision: float
    max_boxes_per_sample: int
    mean_ap_weight: float
    taxonomy: Taxonomy = field(default=NUSCENES, compare=False)

    named: ClassVar[tuple[str, ...]] = NAMED_CONFIGS  # the configurations shipped (nuparquet/data/<name>.json)
    default: ClassVar[str] = DEFAULT_CONFIG

    @property
    def class_names(self) -> tuple[str, ...]:
        return tuple(self.class_range)

    def serialize(self) -> dict:
        """The devkit's `DetectionConfig.serialize()` (the "cfg" of metrics_summary.json)."""
        return {"class_range": dict(self.class_range), "dist_fcn": self.dist_fcn, "dist_ths": list(self.dist_ths),
                "dist_th_tp": self.dist_th_tp, "min_recall": self.min_recall, "min_precision": self.min_precision,
                "max_boxes_per_sample": self.max_boxes_per_sample, "mean_ap_weight": self.mean_ap_weight}

    @classmethod
    def from_dict(cls, content, where: str = "config") -> DetectionConfig:
        """Check `content` (a parsed devkit config) and build the config; UsageError naming what is wrong."""
        if not isinstance(content, dict):
            raise UsageError(f"{where}: expected a JSON object with {', '.join(_FIELDS)}")
        missing = [name for name in _FIELDS if name not in content]
        if missing:
            raise UsageError(f"{where}: missing {', '.join(missing)}")
        class_range = content["class_range"]
        taxonomy = taxonomy_of(class_range) if isinstance(class_range, dict) else None
        if taxonomy is None:
            given = sorted(class_range) if isinstance(class_range, dict) else class_range
            expected = "; or ".join(f"{', '.join(t.detection_names)} ({t.family})" for t in TAXONOMIES.values())
            raise UsageError(f"{where}: class_range must give a range for each detection class of one devkit "
                             f"and nothing else: {expected}; got {given}")
        for name, value in class_range.items():
            if not _is_number(value) or not value > 0:
                raise UsageError(f"{where}: class_range[{name!r}] must be a positive number of metres, got {value!r}")
        if content["dist_fcn"] not in DISTANCE_FUNCTIONS:
            raise UsageError(f"{where}: dist_fcn must be one of {', '.join(DISTANCE_FUNCTIONS)}, "
                             f"got {content['dist_fcn']!r}")
        dist_ths = content["dist_ths"]
        if (not isinstance(dist_ths, list) or not dist_ths
                or not all(_is_number(t) and t > 0 for t in dist_ths)):
            raise UsageError(f"{where}: dist_ths must be a non-empty list of positive numbers, got {dist_ths!r}")
        if len(set(dist_ths)) != len(dist_ths):
            raise UsageError(f"{where}: dist_ths lists a threshold twice: {dist_ths!r}")
        if not _is_number(content["dist_th_tp"]) or content["dist_th_tp"] not in dist_ths:
            raise UsageError(f"{where}: dist_th_tp must be one of dist_ths {dist_ths!r}, got {content['dist_th_tp']!r}")
        min_recall, min_precision = content["min_recall"], content["min_precision"]
        if not _is_number(min_recall) or not 0 <= min_recall <= 1:
            raise UsageError(f"{where}: min_recall must be in [0, 1], got {min_recall!r}")
        if not _is_number(min_precision) or not 0 <= min_precision < 1:
            raise UsageError(f"{where}: min_precision must be in [0, 1), got {min_precision!r}")
        max_boxes = content["max_boxes_per_sample"]
        if isinstance(max_boxes, bool) or not isinstance(max_boxes, int) or max_boxes < 1:
            raise UsageError(f"{where}: max_boxes_per_sample must be a positive integer, got {max_boxes!r}")
        if not _is_number(content["mean_ap_weight"]) or content["mean_ap_weight"] < 0:
            raise UsageError(f"{where}: mean_ap_weight must be a non-negative number, "
                             f"got {content['mean_ap_weight']!r}")
        return cls(class_range=dict(class_range), dist_fcn=content["dist_fcn"], dist_ths=tuple(dist_ths),
                   dist_th_tp=content["dist_th_tp"], min_recall=min_recall, min_precision=min_precision,
                   max_boxes_per_sample=max_boxes, mean_ap_weight=content["mean_ap_weight"], taxonomy=taxonomy)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def named_config(name: str, config_class=DetectionConfig):
    """A configuration shipped with the devkit, by name (`config_class.named`: DetectionConfig's, or another
    evaluation's config class with `named`, `default` and `from_dict`, such as the tracking one)."""
    if name not in config_class.named:
        raise UsageError(f"unknown configuration {name!r}; known: {', '.join(config_class.named)} "
                         "(or give a devkit-format JSON with --config-file)")
    text = (resources.files("nuparquet") / "data" / f"{name}.json").read_text()
    return config_class.from_dict(json.loads(text), where=name)


def config_from_file(path: str | Path, config_class=DetectionConfig):
    """A configuration from a JSON file in the devkit's format (`config_class.serialize()`)."""
    path = Path(path)
    try:
        content = json.loads(path.read_text())
    except FileNotFoundError:
        raise UsageError(f"--config-file {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"--config-file {path}: cannot be read ({exc})") from exc
    except json.JSONDecodeError as exc:
        raise UsageError(f"--config-file {path}: not valid JSON ({exc})") from exc
    return config_class.from_dict(content, where=str(path))


def resolve_config(config=None, config_file: str | Path | None = None, config_class=DetectionConfig,
                   default: str | None = None):
    """The configuration asked for: a `config_class` instance as given, `config_file`, else the named `config`
    (`default`, else `config_class.default`, when none is named)."""
    if isinstance(config, config_class):
        if config_file is not None:
            raise UsageError("give a configuration or a configuration file, not both")
        return config
    if config_file is not None:
        if config not in (None, config_class.default, default):
            raise UsageError("--config and --config-file both given; use one")
        return config_from_file(config_file, config_class)
    return named_config(config or default or config_class.default, config_class)
