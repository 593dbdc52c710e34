"""The panoptic evaluation's pictures (the devkit draws none for this task), written as PNG into `DIR/plots/`:
`pq_per_class.png` (PQ, SQ and RQ of each challenge class side by side, the mean PQ as a line) and, for
panoptic-tracking, `ptq_per_class.png` (PTQ and sPTQ of each class, the mean PTQ as a line). The bars are drawn
by the lidarseg pictures' one `class_bars_figure`. A class the split neither holds nor predicts has the devkit's
0 (its divisions are guarded by an epsilon, not NaN)."""

from __future__ import annotations

from pathlib import Path

from nuparquet.evaluation.plots import _save
from nuparquet.evaluation.segmentation.plots import CLASSES, class_bars_figure


def pq_figure(segmentation: dict):
    """PQ, SQ, RQ per class of the devkit's segmentation dict, its overall PQ as a dashed line."""
    series = {key: [segmentation[c][key] for c in CLASSES] for key in ("PQ", "SQ", "RQ")}
    return class_bars_figure(CLASSES, series, mean=("PQ", segmentation["all"]["PQ"]), ylabel="quality",
                             title="Panoptic quality per class")


def ptq_figure(tracking: dict):
    """PTQ and sPTQ per class of the devkit's tracking dict, its overall PTQ as a dashed line."""
    series = {key: [tracking[c][key] for c in CLASSES] for key in ("PTQ", "sPTQ")}
    return class_bars_figure(CLASSES, series, mean=("PTQ", tracking["all"]["PTQ"]), ylabel="quality",
                             title="Panoptic tracking quality per class")


def write_plots(plot_dir: Path, metrics: dict) -> list[Path]:
    plot_dir.mkdir(parents=True, exist_ok=True)
    written = [_save(pq_figure(metrics["segmentation"]), plot_dir / "pq_per_class.png")]
    if "tracking" in metrics:
        written.append(_save(ptq_figure(metrics["tracking"]), plot_dir / "ptq_per_class.png"))
    return written
