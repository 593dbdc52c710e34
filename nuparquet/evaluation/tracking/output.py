"""Writing a tracking evaluation: DIR/metrics_summary.json, DIR/metrics_details.json, DIR/tracks/,
DIR/predicted_tracks/, DIR/slices* (with --by) and DIR/plots/*.png, all into a hidden sibling of DIR renamed
into place (`nuparquet.atomic.atomic_directory`)."""

from __future__ import annotations

from pathlib import Path

from nuparquet.evaluation.run import _write_json, slug
from nuparquet.evaluation.tracking.config import TrackingConfig

SUMMARY_NAME = "metrics_summary.json"
DETAILS_NAME = "metrics_details.json"


def write_result(out: Path, result, evaluation, config: TrackingConfig, *, plots: bool, reporter) -> None:
    """Everything of `result` into `out` (checked before the work: empty, or to be replaced), atomically."""
    from nuparquet.atomic import atomic_directory

    with atomic_directory(out, overwrite=True) as partial:
        _write_json(partial / SUMMARY_NAME, result.summary)
        _write_json(partial / DETAILS_NAME, result.details)
        for name, table in (("tracks", result.tracks), ("predicted_tracks", result.predicted_tracks)):
            (partial / name).mkdir()
            table.write_parquet(partial / name / "part-00000.parquet")
        if result.slices is not None:
            result.slices.write_parquet(partial / "slices.parquet")
            for (by, label), summary in result.slice_summaries.items():
                folder = partial / "slices" / slug(by) / slug(label)
                folder.mkdir(parents=True, exist_ok=True)
                _write_json(folder / SUMMARY_NAME, summary)
                _write_json(folder / DETAILS_NAME, result.slice_details[(by, label)])
        if plots:
            reporter.advance(step="plots")
            from nuparquet.evaluation.tracking.plots import write_plots

            write_plots(partial / "plots", result.details, config)


def _number_format(metric: str) -> str:
    """The devkit's `metric_name_to_print_format`."""
    if metric in ("amota", "amotp", "motar", "recall", "mota", "motp"):
        return "%.3f"
    if metric in ("tid", "lgd"):
        return "%.2f"
    if metric == "faf":
        return "%.1f"
    return "%d"


def format_summary(summary: dict) -> str:
    """The text the devkit's `print_final_metrics` prints for a metrics_summary.json (for the CLI to show)."""
    import math

    labels = summary["label_metrics"]
    metrics = list(labels)
    lines = ["### Final results ###", "", "Per-class results:", "\t\t" + "\t".join(m.upper() for m in metrics)]
    for name in sorted(next(iter(labels.values()))):
        cells = []
        for metric in metrics:
            value = labels[metric][name]
            cells.append(("%f" if math.isnan(value) else _number_format(metric)) % value)
        lines.append(name[:7].ljust(8) + "".join(f"\t{cell}" for cell in cells))
    lines += ["", "Aggregated results:"]
    for metric in metrics:
        value = summary[metric]
        form = _number_format(metric)
        lines.append(f"{metric.upper()}\t" + ("nan" if math.isnan(value) and form == "%d" else form % value))
    lines.append("Eval time: %.1fs" % summary["eval_time"])
    return "\n".join(lines)
