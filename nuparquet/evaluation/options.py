"""What `nuparquet eval` (and `nuparquet.evaluation.evaluate`) can be asked to do, declared once: each field is
a keyword of `EvalOptions` and a flag of the CLI (`nuparquet.cli.arguments.add_options`). Light on purpose:
the CLI builds its parser from it without loading the evaluation."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from nuparquet.options import check_choices, option

_BY_HELP = ("distance, visibility, attribute, location, night, rain, scene, or any column of the annotations or "
            "scenes datasets")


@dataclass
class EvalOptions:
    """How to evaluate a submission: which benchmark, which split, which settings, which slices (the submission and
    where the metrics go are the verb's arguments: `evaluate(ds, results, out, ...)`)."""

    task: Literal["detection", "tracking", "lidarseg", "panoptic", "panoptic-tracking", "prediction"] = option(
        "detection", help="the benchmark: detection (DetectionEval: mAP, TP errors, NDS; default), tracking "
        "(TrackingEval: AMOTA, AMOTP, MOTA, IDS...), lidarseg (LidarSegEval: mIoU, frequency-weighted IoU; "
        "--results is the submission folder), panoptic (NuScenesPanopticEval segmentation: PQ, SQ, RQ, mIoU, "
        "PQ-dagger), panoptic-tracking (its tracking too: PAT, LSTQ, PTQ, sPTQ, MOTSA...; --results the folder), "
        "prediction (compute_metrics: MinADEK, MinFDEK, MissRateTopK, OffRoadRate)")
    split: str = option("val", help="the split evaluated: train, val, test, mini_train, mini_val, train_detect, "
                        "train_track, or a custom split of <dataroot>/<version>/splits.json (default val)")
    config: str | None = option(None, metavar="NAME",
                                help="the devkit configuration by name (default: the task's: detection_cvpr_2019, "
                                "or truckscenes-devkit's detection_cvpr_2024 for a MAN TruckScenes dataset; "
                                "tracking_nips_2019, predict_2020_icra)")
    config_file: str | Path | None = option(
        None, metavar="CONFIG.json", help="a configuration in the devkit's JSON format instead of --config")
    by: tuple[str, ...] = option((), metavar="DIM,...", help=f"also evaluate per slice of {_BY_HELP} "
                                 "(comma-separated for several; see docs: how predictions are placed in slices)")
    bins: tuple[str, ...] = option(
        (), metavar="EDGES", help="bin edges for --by distance (metres, default 0,10,20,30,40,50) and numeric "
        "columns, e.g. 0,20,40")
    plots: bool = option(True, help="write the task's plots as PNG into DIR/plots: the devkit's PR and TP curves "
                         "(detection, tracking), IoU per class and the confusion matrix (lidarseg), PQ/SQ/RQ and PTQ per "
                         "class (panoptic tasks), the predicted trajectories of the 8 agents of largest final error "
                         "over the map (prediction: plots/trajectories/); --no-plots: skip")
    min_inst_points: int = option(15, metavar="N", help="panoptic tasks: the fewest points of an instance "
                                  "counted as a false negative or positive (the devkit's --min_inst_points; default 15)")
    tags: bool = option(False, help="MAN TruckScenes detection: also evaluate each scene tag of its devkit "
                        "(weather.rain, area.highway, ...: truckscenes-devkit's --evaluate_tags), one entry per tag in "
                        "metrics_summary.json beside \"all\"")
    overwrite: bool = option(False, help="replace DIR if it already holds files")

    def __post_init__(self) -> None:
        check_choices(self)
