"""Prediction evaluation: nuparquet's `evaluate_prediction` end to end vs the devkit's `NuScenes` load +
`PredictHelper` + `load_prediction_config` (its four drivable-area masks) + `compute_metrics`, each in a fresh
process.

    .venv/bin/python benchmarks/eval_prediction.py [--scenes 50] [--modes 12] [--repeats 3]

Data: the synthetic set with trainval's shape (`bench_data.py`; `--scenes N` x 40 samples, v1.0-trainval, at least
44 scenes so that its logs cover the four maps the devkit's `load_all_maps` opens), evaluated on split val (its
scenes whose names are in the devkit's val list), with a submission made from the ground truth (cached beside the
set): every agent of a vehicle category at every second keyframe whose 6 s future is complete, `--modes` modes of
its future plus noise (0.3 m to 5 m sd, a tenth of the modes 20 m: off the road), probabilities on a 0.05 grid
(ties).

- nuparquet: a fresh process running `evaluate_prediction(OUT, RESULTS, DIR, split="val")` (open, read and check the
  submission, walk the futures, metrics, off-road tiles, write the metrics and agents/modes tables).
- devkit: a fresh process running `NuScenes(...)`, `PredictHelper`, `load_prediction_config` (`init_s`) and
  `compute_metrics` on `json.load` of the submission (`metrics_s`).
Afterwards both metric dicts are compared (exactly).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's nuparquet, in every child too

TARGET_RATIO = 50.0
SPLIT = "val"
VEHICLES = ("vehicle.car", "vehicle.truck", "vehicle.bus.rigid", "vehicle.bus.bendy", "vehicle.construction",
            "vehicle.trailer", "vehicle.emergency.police", "vehicle.emergency.ambulance")


def devkit_child(dataroot: str, version: str, results: str, out_path: str) -> None:
    start = time.perf_counter()
    from nuscenes import NuScenes
    from nuscenes.eval.prediction.compute_metrics import compute_metrics
    from nuscenes.eval.prediction.config import load_prediction_config
    from nuscenes.prediction import PredictHelper

    nusc = NuScenes(version=version, dataroot=dataroot, verbose=False)
    helper = PredictHelper(nusc)
    config = load_prediction_config(helper, "predict_2020_icra.json")
    initialised = time.perf_counter()
    with open(results) as f:
        predictions = json.load(f)
    metrics = compute_metrics(predictions, helper, config)
    done = time.perf_counter()
    Path(out_path).write_text(json.dumps(metrics, indent=2))
    print(json.dumps({"init_s": initialised - start, "metrics_s": done - initialised, "total_s": done - start}))
    sys.stdout.flush()
    os._exit(0)


def ours_child(out: str, results: str, out_dir: str) -> None:
    start = time.perf_counter()
    from nuparquet.evaluation.prediction import evaluate_prediction

    evaluate_prediction(out, results, out_dir, split=SPLIT, overwrite=True)
    print(json.dumps({"total_s": time.perf_counter() - start}))
    sys.stdout.flush()
    os._exit(0)


def make_submission(out: Path, path: Path, modes: int, seed: int = 0) -> dict:
    """The submission of the module docstring, written to `path`; returns its counts."""
    import numpy as np
    import polars as pl

    import nuparquet
    from nuparquet.evaluation.splits import split_scene_names
    from nuparquet.frames.annotation_chains import AnnotationChains

    ds = nuparquet.open(out)
    names = split_scene_names(SPLIT)
    ann = (ds.scan("annotations").filter(pl.col("scene_name").is_in(names)
                                         & pl.col("category_name").cast(pl.String).is_in(VEHICLES))
           .select("sample_token", "instance_token", "timestamp").collect())
    keyframes = ann["timestamp"].unique().sort()
    ann = ann.filter(pl.col("timestamp").is_in(keyframes.gather_every(2).implode()))
    chains, _ = AnnotationChains.of(ds)
    rows = chains.rows_at(ann["sample_token"].to_list(), ann["instance_token"].to_list())
    windows = chains.windows(rows, 6, "next")
    rng = np.random.default_rng(seed)
    records = []
    for i, window in enumerate(windows):
        if len(window) != 12:
            continue
        future = chains.translation[window][:, :2]
        scale = np.where(rng.uniform(size=modes) < 0.1, 20.0, rng.uniform(0.3, 5.0, modes))
        prediction = future[None] + rng.normal(0, 1, (modes, 12, 2)) * scale[:, None, None]
        probabilities = np.round(rng.uniform(0, 1, modes) / 0.05) * 0.05
        records.append({"instance": ann["instance_token"][i], "sample": ann["sample_token"][i],
                        "prediction": prediction.tolist(), "probabilities": probabilities.tolist()})
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(records))
    os.replace(tmp, path)
    return {"agents": len(records), "modes": modes}


def submission_path(out: Path, modes: int) -> Path:
    from bench_data import PARAMS, _params_match

    folder = out.parent / f"{out.name}-prediction-{modes}"
    dataset = json.loads((out / PARAMS).read_text()) if (out / PARAMS).is_file() else None
    params = {"prediction_submission": {"out": str(out.resolve()), "modes": modes, "dataset": dataset}}
    path = folder / "predictions.json"
    if path.is_file() and _params_match(folder, params):
        return path
    folder.mkdir(parents=True, exist_ok=True)
    counts = make_submission(out, path, modes)
    (folder / PARAMS).write_text(json.dumps({**params, **counts}) + "\n")
    return path


def run(repeats: int = 3, scenes: int = 50, modes: int = 12) -> dict:
    import bench_data as datasets
    from harness import Row, log, megabytes, python_child, repeat, run_child, seconds, summarize, times

    root, out = datasets.scenes_root(scenes), datasets.scenes_out(scenes)
    results = submission_path(out, modes)
    counts = json.loads((results.parent / datasets.PARAMS).read_text())
    log(f"prediction: {counts['agents']} agents x {modes} modes of split {SPLIT} ({scenes} scenes)")
    with tempfile.TemporaryDirectory(prefix="bench-prediction-") as tmp:
        ours_dir, devkit_file = Path(tmp) / "ours", Path(tmp) / "devkit.json"
        cmd = python_child(__file__, "--ours-child", out, results, ours_dir)
        ours = summarize(repeat(cmd, repeats, label="evaluate_prediction"))
        devkit_cmd = python_child(__file__, "--devkit-child", root, datasets.TRAINVAL_VERSION, results, devkit_file)
        devkit_run = run_child(devkit_cmd, timeout_s=6 * 3600)
        log(f"  devkit {devkit_run.wall_s:.1f} s, {devkit_run.max_rss_mb:.0f} MiB")
        devkit = summarize([devkit_run], init_s="init_s", metrics_s="metrics_s")
        same = (ours_dir / "prediction_metrics.json").read_text() == devkit_file.read_text()
    ratio = devkit["wall_s"] / ours["wall_s"]
    rss_fraction = ours["max_rss_mb"] / devkit["max_rss_mb"]
    rows = [Row(
        id="prediction",
        benchmark=f"prediction evaluation, split {SPLIT} ({counts['agents']:,} agents x {modes} modes; "
        f"{scenes}-scene set), end to end in a fresh process",
        ours=f"{seconds(ours['wall_s'])} ({seconds(ours['cpu_s'])} CPU), {megabytes(ours['max_rss_mb'])} peak",
        reference=f"devkit {seconds(devkit['wall_s'])} (NuScenes + PredictHelper + config with its masks "
        f"{seconds(devkit['init_s'])}, compute_metrics {seconds(devkit['metrics_s'])}), "
        f"{megabytes(devkit['max_rss_mb'])} peak",
        ratio=f"{times(ratio)}, {rss_fraction:.2f} of the memory",
        target=f"≥ {TARGET_RATIO:.0f}×, same metrics",
        met=ratio >= TARGET_RATIO and same,
        note="metric files " + ("identical" if same else "DIFFER"))]
    return {"name": "prediction", "scenes": scenes, "command": " ".join(map(str, cmd)),
            "devkit": {**devkit, "command": " ".join(map(str, devkit_cmd))}, "nuparquet": ours,
            "submission": counts, "same_metrics": same, "ratio": ratio, "rss_fraction": rss_fraction, "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=50, help="synthetic scenes of the set (default 50; >= 44)")
    parser.add_argument("--modes", type=int, default=12)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--devkit-child", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--ours-child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.devkit_child:
        devkit_child(*args.devkit_child)
        return
    if args.ours_child:
        ours_child(*args.ours_child)
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes, args.modes))


if __name__ == "__main__":
    main()
