"""`nuparquet eval OUT --results results.json --split val --out DIR [--by ...]`: the nuScenes detection metrics of
a submission, exactly as nuscenes-devkit's DetectionEval computes them. Flags come from
`nuparquet.evaluation.options.EvalOptions`; only `OUT` and `--quiet` are the CLI's own."""

from __future__ import annotations

import argparse
import math

from nuparquet.cli.arguments import add_options, options_from
from nuparquet.cli.progress import bars
from nuparquet.evaluation.options import EvalOptions

_EPILOG = """\
examples:
  nuparquet eval OUT --results results_nusc.json --split val --out eval/
  nuparquet eval OUT --results results_nusc.json --split mini_val --by distance,night --out eval/
  nuparquet eval OUT --results results_nusc.json --by num_lidar_pts --bins 0,1,5,20,100,100000
  nuparquet eval OUT --task panoptic-tracking --results panoptic_results/ --split val --out eval/
  nuparquet eval OUT --task prediction --results predictions.json --split val --out eval/

Writes DIR/metrics_summary.json and DIR/metrics_details.json (the devkit's files: keys, structure and values),
DIR/plots/*.png (the devkit's PR and TP curves), DIR/predictions/ (one row per predicted box: sample, scene,
class, score, whether it was evaluated or filtered out, and per threshold the matched annotation and the match
distance) and DIR/ground_truth/ (one row per annotation of a detection class, with the prediction that matched
it), and with --by DIR/slices.parquet and DIR/slices/<by>/<slice>/metrics_*.json.

Slices: a ground-truth box belongs to the slice of its own value; a prediction to the slice of its own value
where it has one (distance to the ego vehicle, its sample's scene, location, night, rain), else to the slice of
the ground truth it matched at the TP threshold (2 m): an unmatched prediction counts as a false positive in
every slice (for --by attribute: in the slice of the attribute it predicted). See nuparquet/evaluation/slices.py.

Every sample of the split must be in the submission (an empty list where nothing was detected). Exit codes:
0 done, 1 a submission or dataset the devkit would refuse (the message names the sample and the box), 2 bad
arguments (unknown split, configuration or slice; an --out that holds files without --overwrite).
"""


def register(sub) -> None:
    p = sub.add_parser(
        "eval",
        help="evaluate a submission (detection: mAP, NDS; tracking: AMOTA; lidarseg: mIoU; panoptic: PQ; "
        "panoptic-tracking: PAT, LSTQ; prediction: MinADE_k, OffRoadRate) exactly as "
        "nuscenes-devkit, per slice too",
        description="Compute the nuScenes detection metrics of a submission (results.json) from the converted "
        "dataset, exactly as nuscenes-devkit's DetectionEval does (class ranges, bike-rack filter, greedy "
        "centre-distance matching, 101-point precision, TP errors, NDS), optionally per slice (--by), and write "
        "the devkit's metric files, its plots as PNG, and the predictions and ground truth as Parquet. A MAN "
        "TruckScenes output is evaluated as truckscenes-devkit's DetectionEval does (detection_cvpr_2024, its "
        "12 classes, --tags for its per-scene-tag metrics); --task picks the other nuScenes benchmarks.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dataset", metavar="OUT", help="a directory written by `nuparquet convert`")
    p.add_argument("--results", metavar="RESULTS.json", required=True, help="the submission, nuScenes format: "
                   "detection/tracking {\"meta\": {...}, \"results\": {sample_token: [box, ...]}}; lidarseg a folder "
                   "of lidarseg/<split>/<token>_lidarseg.bin and <split>/submission.json; panoptic and "
                   "panoptic-tracking a folder of panoptic/<split>/<token>_panoptic.npz and <split>/submission.json"
                   "; prediction a JSON list of {instance, sample, prediction, probabilities}")
    p.add_argument("--out", metavar="DIR", help="write metrics_summary.json, metrics_details.json, plots/, "
                   "predictions/, ground_truth/ (and slices/ with --by) here (panoptic: <segmentation|tracking>-"
                   "result.json, classes.parquet, instances.parquet); without it the metrics are only printed")
    add_options(p, EvalOptions)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def _number(value: float, width: int = 6) -> str:
    return "nan".ljust(width) if isinstance(value, float) and math.isnan(value) else f"{value:<{width}.3f}"


def print_summary(summary: dict) -> None:
    """The devkit's printout of `DetectionEval.main`."""
    from nuparquet.evaluation.classes import MEAN_TP_NAMES

    print(f"mAP: {summary['mean_ap']:.4f}")
    for metric, value in summary["tp_errors"].items():
        print(f"{MEAN_TP_NAMES[metric]}: {value:.4f}")
    print(f"NDS: {summary['nd_score']:.4f}")
    print(f"Eval time: {summary['eval_time']:.1f}s")
    print()
    print("Per-class results:")
    print("%-20s\t%-6s\t%-6s\t%-6s\t%-6s\t%-6s\t%-6s" % ("Object Class", "AP", "ATE", "ASE", "AOE", "AVE", "AAE"))
    for name, ap in summary["mean_dist_aps"].items():
        errors = summary["label_tp_errors"][name]
        print("%-20s\t" % name + "\t".join(_number(v) for v in (ap, errors["trans_err"], errors["scale_err"],
                                                                 errors["orient_err"], errors["vel_err"],
                                                                 errors["attr_err"])))


def print_tags(summary: dict) -> None:
    """truckscenes-devkit's "Per-tag results" table (`--tags`): one line per scene tag."""
    print()
    print("Per-tag results:")
    print("%-22s\t%-6s\t%-6s\t%-6s\t%-6s\t%-6s\t%-6s\t%-6s" % ("Scene Tag", "mAP", "mATE", "mASE", "mAOE", "mAVE",
                                                          "mAAE", "NDS"))
    for tag, metrics in summary.items():
        if tag in ("all", "eval_time", "meta"):
            continue
        errors = metrics["tp_errors"]
        print("%-22s\t" % tag + "\t".join(_number(v) for v in (
            metrics["mean_ap"], errors["trans_err"], errors["scale_err"], errors["orient_err"], errors["vel_err"],
            errors["attr_err"], metrics["nd_score"])))


def print_lidarseg(metrics: dict) -> None:
    """The devkit's result dict, one class a line (LidarSegEval's verbose printout is its JSON dump)."""
    print(f"mIoU: {metrics['miou']:.4f}")
    print(f"fwIoU: {metrics['freq_weighted_iou']:.4f}")
    print()
    print("Per-class IoU:")
    for name, iou in metrics["iou_per_class"].items():
        print(f"{name:<20}\t{_number(iou)}")


def print_panoptic(metrics: dict) -> None:
    """Each task's "all" figures, then one class a line (NuScenesPanopticEval's verbose printout is its JSON)."""
    for task, figures in metrics.items():
        print(f"Panoptic nuScenes {task}:")
        print("  " + "  ".join(f"{key}: {_number(value, 0)}" for key, value in figures["all"].items()))
        keys = list(next(value for name, value in figures.items() if name != "all"))
        print(f"{'Class':<20}\t" + "\t".join(f"{key:<6}" for key in keys))
        for name, values in figures.items():
            if name != "all":
                print(f"{name:<20}\t" + "\t".join(_number(values[key]) for key in keys))


def print_prediction(metrics: dict) -> None:
    """The devkit's metrics dict, one line per metric and aggregator."""
    for name, aggregations in metrics.items():
        for aggregator, values in aggregations.items():
            print(f"{name} ({aggregator}): {', '.join(_number(v) for v in values)}")


def run(args) -> int:
    from nuparquet.cli.output import print_frame
    from nuparquet.evaluation.run import evaluate

    options = options_from(args, EvalOptions)
    result = evaluate(args.dataset, args.results, args.out, options, on_progress=bars(not args.quiet))
    if options.task == "tracking":
        from nuparquet.evaluation.tracking.output import format_summary

        print(format_summary(result.summary))
    elif options.task == "lidarseg":
        print_lidarseg(result.metrics)
    elif options.task in ("panoptic", "panoptic-tracking"):
        print_panoptic(result.metrics)
    elif options.task == "prediction":
        print_prediction(result.metrics)
        if args.out is not None and options.plots:  # the pictures are the rendering layer's
            from pathlib import Path

            from nuparquet.rendering.pictures.trajectories import write_trajectory_plots

            write_trajectory_plots(Path(args.out) / "plots" / "trajectories", args.dataset, result)
    else:
        print_summary(result.metrics.serialize())
        if options.tags:
            print_tags(result.summary)
    if result.slices is not None:
        for by in dict.fromkeys(result.slices["by"].to_list()):
            table = result.slices.filter(result.slices["by"] == by).drop("by")
            print_frame(table.select(table.columns[:10]), "table", title=f"Slices by {by}:")
    for note in result.notes:
        print(f"note: {note}")
    if result.out is not None:
        print(f"written: {result.out}")
    return 0
