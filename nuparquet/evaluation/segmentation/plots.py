"""The lidarseg evaluation's pictures (the devkit draws none for this task), written as PNG into `DIR/plots/`:
`iou_per_class.png` (the IoU of each challenge class as a bar, the mIoU as a line) and `confusion.png` (the
confusion matrix, each ground-truth row as fractions of its points, the ignore class left out)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nuparquet.evaluation.plots import DPI, _save, plt
from nuparquet.evaluation.segmentation.classes import COARSE_NAMES

CLASSES = COARSE_NAMES[1:]  # the devkit's included challenge classes, the ignore class left out


def row_fractions(confusion: np.ndarray) -> np.ndarray:
    """(C-1, C-1) float64: each ground-truth class's points (row) as fractions predicted as each class, the
    ignore class (index 0) left out; NaN rows for classes without ground-truth points."""
    scored = confusion[1:, 1:].astype(np.float64)
    totals = scored.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(totals > 0, scored / totals, np.nan)


def class_bars_figure(classes, series: dict, *, mean: tuple[str, float], ylabel: str, title: str):
    """One bar per class of each series ({label: per-class values in `classes`' order}), side by side, NaN drawn
    as no bar (height 0); `mean` (label, value) as a dashed line. Shared by the lidarseg and panoptic pictures."""
    colors = ("tab:blue", "tab:orange", "tab:green")
    width = 0.8 / len(series)
    fig, ax = plt.subplots(figsize=(9, 4.5), dpi=DPI)
    for k, (label, values) in enumerate(series.items()):
        offset = (k - (len(series) - 1) / 2) * width
        ax.bar(np.arange(len(classes)) + offset, np.nan_to_num(np.asarray(values, dtype=np.float64)), width,
               color=colors[k], label=label if len(series) > 1 else None)
    ax.axhline(mean[1], color="tab:red", linestyle="--", label=f"{mean[0]} {mean[1]:.3f}")
    ax.set_xticks(range(len(classes)), classes, rotation=60, ha="right", fontsize=8)
    ax.set_ylim(0, 1)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right")
    fig.tight_layout()  # the rotated class names inside the picture
    return fig


def iou_figure(metrics: dict):
    """The IoU of each challenge class as a bar (none where the class is neither in the ground truth nor
    predicted), the mIoU as a dashed line."""
    classes = CLASSES
    return class_bars_figure(classes, {"IoU": [metrics["iou_per_class"][c] for c in classes]},
                             mean=("mIoU", metrics["miou"]), ylabel="IoU",
                             title="IoU per class (no bar: neither in the ground truth nor predicted)")


def confusion_figure(confusion: np.ndarray):
    """The confusion matrix as each ground-truth class's fractions (`row_fractions`)."""
    classes = CLASSES
    fig, ax = plt.subplots(figsize=(7.5, 7), dpi=DPI)
    shown = ax.imshow(row_fractions(confusion), vmin=0, vmax=1, cmap="viridis")
    ax.set_xticks(range(len(classes)), classes, rotation=90, fontsize=7)
    ax.set_yticks(range(len(classes)), classes, fontsize=7)
    ax.set_xlabel("predicted class")
    ax.set_ylabel("ground-truth class")
    ax.set_title("Confusion: fraction of each class's points (blank: no points)", fontsize=10)
    fig.colorbar(shown, ax=ax, fraction=0.046)
    fig.tight_layout()
    return fig


def write_plots(plot_dir: Path, metrics: dict, confusion: np.ndarray) -> list[Path]:
    plot_dir.mkdir(parents=True, exist_ok=True)
    return [_save(iou_figure(metrics), plot_dir / "iou_per_class.png"),
            _save(confusion_figure(confusion), plot_dir / "confusion.png")]
