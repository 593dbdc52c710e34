"""The devkit's evaluation plots (`eval/detection/render.py`), drawn the same way but written as PNG (headless
matplotlib, Agg): `summary.png` (PR and TP curves of every class), `<class>_pr.png`, `<class>_tp.png` and
`dist_pr_<threshold>.png`, into `DIR/plots/`."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless; must precede pyplot

import matplotlib.pyplot as plt  # noqa: E402

from nuparquet.evaluation.classes import PRETTY_TP_METRICS, TP_METRICS, TP_METRICS_UNITS  # noqa: E402
from nuparquet.evaluation.config import DetectionConfig  # noqa: E402
from nuparquet.evaluation.metrics import DetectionMetrics, MetricData  # noqa: E402

DPI = 100


def _setup_axis(ax, xlabel=None, ylabel=None, xlim=None, ylim=None, title=None, min_precision=None, min_recall=None):
    """The devkit's `setup_axis` (spines hidden, large ticks, the min recall / precision as dashed lines)."""
    ax.get_xaxis().tick_bottom()
    ax.tick_params(labelsize=16)
    ax.get_yaxis().tick_left()
    for side in ("top", "right", "bottom", "left"):
        ax.spines[side].set_visible(False)
    if title is not None:
        ax.set_title(title, size=24)
    if xlabel is not None:
        ax.set_xlabel(xlabel, size=16)
    if ylabel is not None:
        ax.set_ylabel(ylabel, size=16)
    if xlim is not None:
        ax.set_xlim(0, xlim)
    if ylim is not None:
        ax.set_ylim(0, ylim)
    if min_recall is not None:
        ax.axvline(x=min_recall, linestyle="--", color=(0, 0, 0, 0.3))
    if min_precision is not None:
        ax.axhline(y=min_precision, linestyle="--", color=(0, 0, 0, 0.3))
    return ax


def _pretty(name: str, config: DetectionConfig) -> str:
    return config.taxonomy.pretty_names.get(name, name)


def class_pr_curve(ax, data: dict, metrics: DetectionMetrics, name: str) -> None:
    """Precision against recall of one class, one curve per matching threshold."""
    for (class_name, threshold), md in data.items():
        if class_name == name:
            ap = metrics.label_aps[name][threshold]
            ax.plot(md.recall, md.precision, label=f"Dist. : {threshold}, AP: {ap * 100:.1f}")
    ax.legend(loc="best")


def class_tp_curve(ax, md: MetricData, metrics: DetectionMetrics, name: str, min_recall: float) -> None:
    """The TP errors of one class against recall, at the TP threshold, up to the highest recall reached."""
    min_recall_ind = round(100 * min_recall)
    errors = metrics.label_tp_errors[name]
    defined = [m for m in TP_METRICS if not math.isnan(errors[m])]
    if min_recall_ind <= md.max_recall_ind and defined:
        ylimit = max(max(getattr(md, m)[min_recall_ind:md.max_recall_ind + 1]) for m in defined) * 1.1
    else:
        ylimit = 1.0
    ax.set_ylim(0, ylimit if ylimit > 0 else 1.0)
    for metric in TP_METRICS:
        tp = errors[metric]
        if not math.isnan(tp) and min_recall_ind <= md.max_recall_ind:
            recall, error = md.recall[:md.max_recall_ind + 1], getattr(md, metric)[:md.max_recall_ind + 1]
        else:
            recall, error = [], []
        if math.isnan(tp):
            label = f"{PRETTY_TP_METRICS[metric]}: n/a"
        elif min_recall_ind > md.max_recall_ind:
            label = f"{PRETTY_TP_METRICS[metric]}: nan"
        else:
            label = f"{PRETTY_TP_METRICS[metric]}: {tp:.2f} ({TP_METRICS_UNITS[metric]})"
        ax.plot(recall, error, label=label)
    ax.axvline(x=md.max_recall, linestyle="-.", color=(0, 0, 0, 0.3))
    ax.legend(loc="best")


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def write_plots(plot_dir: Path, data: dict, metrics: DetectionMetrics, config: DetectionConfig) -> list[Path]:
    """Every plot of the devkit's `DetectionEval.render`, as PNG files in `plot_dir` (created)."""
    plot_dir.mkdir(parents=True, exist_ok=True)
    written = []
    names = config.class_names
    fig, axes = plt.subplots(nrows=len(names), ncols=2, figsize=(15, 5 * len(names)), squeeze=False)
    for i, name in enumerate(names):
        title1, title2 = ("Recall vs Precision", "Recall vs Error") if i == 0 else (None, None)
        ax1 = _setup_axis(axes[i, 0], xlim=1, ylim=1, title=title1, min_precision=config.min_precision,
                          min_recall=config.min_recall)
        ax1.set_ylabel(f"{_pretty(name, config)} \n \n Precision", size=20)
        ax2 = _setup_axis(axes[i, 1], xlim=1, title=title2, min_recall=config.min_recall)
        if i == len(names) - 1:
            ax1.set_xlabel("Recall", size=20)
            ax2.set_xlabel("Recall", size=20)
        class_pr_curve(ax1, data, metrics, name)
        class_tp_curve(ax2, data[(name, config.dist_th_tp)], metrics, name, config.min_recall)
    fig.tight_layout()
    written.append(_save(fig, plot_dir / "summary.png"))
    for name in names:
        fig, ax = plt.subplots()
        _setup_axis(ax, title=_pretty(name, config), xlabel="Recall", ylabel="Precision", xlim=1, ylim=1,
                    min_precision=config.min_precision, min_recall=config.min_recall)
        class_pr_curve(ax, data, metrics, name)
        written.append(_save(fig, plot_dir / f"{name}_pr.png"))
        fig, ax = plt.subplots()
        _setup_axis(ax, title=_pretty(name, config), xlabel="Recall", ylabel="Error", xlim=1, min_recall=config.min_recall)
        class_tp_curve(ax, data[(name, config.dist_th_tp)], metrics, name, config.min_recall)
        written.append(_save(fig, plot_dir / f"{name}_tp.png"))
    for threshold in config.dist_ths:
        fig, (ax, legend_ax) = plt.subplots(ncols=2, gridspec_kw={"width_ratios": [4, 1]}, figsize=(7.5, 5))
        _setup_axis(ax, xlabel="Recall", ylabel="Precision", xlim=1, ylim=1, min_precision=config.min_precision,
                    min_recall=config.min_recall)
        for name in names:
            md = data[(name, threshold)]
            ap = metrics.label_aps[name][threshold]
            ax.plot(md.recall, md.precision, label=f"{_pretty(name, config)}: {ap * 100:.1f}%",
                    color=config.taxonomy.colors.get(name))
        handles, labels = ax.get_legend_handles_labels()
        legend_ax.legend(handles, labels, borderaxespad=0)
        legend_ax.axis("off")
        fig.tight_layout()
        written.append(_save(fig, plot_dir / f"dist_pr_{threshold}.png"))
    return written

