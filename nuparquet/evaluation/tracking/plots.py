"""The devkit's tracking plots (`eval/tracking/render.py`: `summary_plot` and `recall_metric_curve`), drawn the
same way but written as PNG (headless matplotlib): `summary.png` (every traditional metric against recall, every
class) and `<metric>.png` for each of the devkit's LEGACY_METRICS, into `DIR/plots/`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nuparquet.evaluation.plots import DPI, _save, _setup_axis, plt
from nuparquet.evaluation.tracking.config import LEGACY_METRICS, TrackingConfig

SUMMARY_METRICS = ("motar", "motp", "mota", "recall", "mt", "ml", "faf", "tp", "fp", "fn", "ids", "frag", "tid", "lgd")
LOG_SCALE = ("mt", "ml", "faf", "tp", "fp", "fn", "ids", "frag")


def recall_metric_curve(ax, details: dict, metric: str, config: TrackingConfig) -> None:
    """One metric against the hypothetical recall of each threshold, one curve per class, from the first reached
    recall level on (the devkit's `recall_metric_curve`)."""
    _setup_axis(ax, xlabel="Recall", ylabel=metric.upper(), xlim=1, min_recall=config.min_recall)
    ax.spines["bottom"].set_visible(True)  # the devkit's show_spines='bottomleft'
    ax.spines["left"].set_visible(True)
    for name, md in details.items():
        confidence = np.array(md["confidence"], dtype=np.float64)
        valid = np.flatnonzero(~np.isnan(confidence))
        if not len(valid):
            continue
        first = valid[0]
        ax.plot(md["recall_hypo"][first:], md[metric][first:], label=config.pretty_tracking_names[name],
                color=config.tracking_colors[name])
    if metric in LOG_SCALE:
        ax.set_yscale("symlog")
    if metric in ("amota", "motar", "recall", "mota"):
        ax.set_ylim(0, 1)
    elif metric != "motp":
        ax.set_ylim(bottom=0)
    ax.legend(loc="upper right", borderaxespad=0)


def write_plots(plot_dir: Path, details: dict, config: TrackingConfig) -> list[Path]:
    """`summary.png` and one `<metric>.png` per legacy metric (the devkit's `TrackingEval.render`), in `plot_dir`."""
    plot_dir.mkdir(parents=True, exist_ok=True)
    ncols = 2
    nrows = int(np.ceil(len(SUMMARY_METRICS) / ncols))
    fig, axes = plt.subplots(nrows=nrows, ncols=ncols, figsize=(7.5 * ncols, 5 * nrows), squeeze=False)
    for i, metric in enumerate(SUMMARY_METRICS):
        recall_metric_curve(axes[i // ncols, i % ncols], details, metric, config)
    fig.tight_layout()
    written = [_save(fig, plot_dir / "summary.png")]
    for metric in LEGACY_METRICS:
        fig, ax = plt.subplots(1, 1, figsize=(7.5, 5), dpi=DPI)
        recall_metric_curve(ax, details, metric, config)
        fig.tight_layout()
        written.append(_save(fig, plot_dir / f"{metric}.png"))
    return written
