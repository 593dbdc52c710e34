"""The prediction evaluation's settings: the devkit's `PredictionConfig`, by name (`predict_2020_icra`, the one of
the nuScenes prediction challenge) or from a JSON file in the devkit's format (`--config-file`).

Values keep the types the JSON gives them: the devkit names the miss rate `MissRateTopK_{tolerance}`, so a
tolerance written `2` reports `MissRateTopK_2` where `2.0` reports `MissRateTopK_2.0`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from nuparquet.errors import UsageError
from nuparquet.evaluation.config import _is_number

NAMED_CONFIGS = ("predict_2020_icra",)
DEFAULT_CONFIG = "predict_2020_icra"
TOP_K_METRICS = ("MinADEK", "MinFDEK", "MissRateTopK")  # the devkit's metrics with k_to_report
METRICS = (*TOP_K_METRICS, "OffRoadRate")
AGGREGATORS = ("RowMean",)
FREQUENCY_HZ = 2  # the devkit's PredictionConfig default (deserialize never reads it)


@dataclass(frozen=True)
class Metric:
    """One metric of the configuration. kind: MinADEK, MinFDEK, MissRateTopK or OffRoadRate; k_to_report: the k
    reported (the top-k metrics); tolerance: metres (MissRateTopK); aggregators: their names (RowMean)."""

    kind: str
    aggregators: tuple[str, ...]
    k_to_report: tuple[int, ...] = ()
    tolerance: float | int | None = None

    @property
    def name(self) -> str:
        """The devkit's `Metric.name`: the key of its results."""
        return f"MissRateTopK_{self.tolerance}" if self.kind == "MissRateTopK" else self.kind


@dataclass(frozen=True)
class PredictionConfig:
    """The devkit's PredictionConfig: the metrics in their order and the seconds of future evaluated."""

    metrics: tuple[Metric, ...]
    seconds: float | int = 6

    named: ClassVar[tuple[str, ...]] = NAMED_CONFIGS
    default: ClassVar[str] = DEFAULT_CONFIG

    def serialize(self) -> dict:
        """The devkit's `PredictionConfig.serialize()`."""
        out = []
        for m in self.metrics:
            entry = {"k_to_report": list(m.k_to_report)} if m.kind in TOP_K_METRICS else {}
            entry |= {"name": m.kind, "aggregators": [{"name": a} for a in m.aggregators]}
            if m.kind == "MissRateTopK":
                entry["tolerance"] = m.tolerance
            out.append(entry)
        return {"metrics": out, "seconds": self.seconds}

    @classmethod
    def from_dict(cls, content, where: str = "config") -> PredictionConfig:
        """Check a devkit-format configuration as `PredictionConfig.deserialize` reads it (UsageError naming the
        metric and the field for what it would refuse or mis-evaluate)."""
        if not isinstance(content, dict) or "metrics" not in content or "seconds" not in content:
            raise UsageError(f"{where}: a prediction configuration is an object with \"metrics\" and \"seconds\"")
        seconds = content["seconds"]
        if not _is_number(seconds) or seconds <= 0:
            raise UsageError(f"{where}: seconds must be a positive number, got {seconds!r}")
        if not isinstance(content["metrics"], list) or not content["metrics"]:
            raise UsageError(f"{where}: metrics must be a non-empty list")
        metrics = []
        for i, entry in enumerate(content["metrics"]):
            here = f"{where}: metrics[{i}]"
            kind = entry.get("name") if isinstance(entry, dict) else None
            if kind not in METRICS:
                raise UsageError(f"{here}: name must be one of {', '.join(METRICS)}, got {kind!r}")
            aggregators = entry.get("aggregators")
            if (not isinstance(aggregators, list) or not aggregators
                    or any(not isinstance(a, dict) or a.get("name") not in AGGREGATORS for a in aggregators)):
                raise UsageError(f"{here} ({kind}): aggregators must be a list of {{\"name\": \"RowMean\"}}")
            k_to_report, tolerance = (), None
            if kind in TOP_K_METRICS:
                k_to_report = entry.get("k_to_report")
                if (not isinstance(k_to_report, list) or not k_to_report
                        or any(type(k) is not int or k < 1 for k in k_to_report)):
                    raise UsageError(f"{here} ({kind}): k_to_report must be a list of positive integers, got "
                                     f"{k_to_report!r}")
            if kind == "MissRateTopK":
                tolerance = entry.get("tolerance")
                if not _is_number(tolerance):
                    raise UsageError(f"{here} ({kind}): tolerance must be a number of metres, got {tolerance!r}")
            metrics.append(Metric(kind=kind, aggregators=tuple(a["name"] for a in aggregators),
                                  k_to_report=tuple(k_to_report), tolerance=tolerance))
        names = [m.name for m in metrics]
        if len(set(names)) != len(names):
            raise UsageError(f"{where}: metric names repeat ({', '.join(names)}): the devkit keys its results by name")
        return cls(metrics=tuple(metrics), seconds=seconds)


def resolve_prediction_config(config=None, config_file=None) -> PredictionConfig:
    """The configuration asked for: a PredictionConfig as given, `config_file`, else the named `config`."""
    from nuparquet.evaluation.config import resolve_config

    return resolve_config(config, config_file, PredictionConfig)
