"""Tracking evaluation: nuparquet's `evaluate_tracking` end to end vs the devkit's `TrackingEval` (its own
`NuScenes` load, motmetrics 1.4.0) end to end, each in a fresh process.

    .venv/bin/python benchmarks/bench_tracking.py [--scenes 100] [--boxes-per-sample 60] [--repeats 3]
                                                  [--ours-only-scenes 850]

Data: the synthetic set with trainval's shape (`bench_data.py`; `--scenes N` x 40 samples, v1.0-trainval),
evaluated on split val (its scenes whose names are in the devkit's val list), with a tracking submission made from
its ground truth (cached beside the set): every annotation of a tracking class as a box of its instance's track
(0.4 m sd noise), a tenth of the boxes dropped (the devkit interpolates them back), one track in twenty given a new
id half-way (an identity switch), one in ten never predicted, track scores on a 0.01 grid with per-box jitter,
and false-positive tracks around the ego vehicle up to `--boxes-per-sample` boxes per sample.

The devkit's tracking evaluation costs minutes per scene of val (every object x 40 thresholds through pandas), so
the ratio is measured on a `--scenes` subset (default 100 scenes: ~18 of them in val), both sides on the same data.
`--ours-only-scenes 850` adds nuparquet's time and memory on the full trainval-scale val split, and the devkit's
`TrackingEval` construction alone there (its NuScenes load, the submission, ground truth, filters and tracks: a
lower bound of its end-to-end time and peak memory, which its `main` only adds to).

- nuparquet: a fresh process running `evaluate_tracking(OUT, RESULTS, DIR, split="val", plots=False)` (open,
  read the submission, load the ground truth, filter, track, score, write the metric files and tracks/).
- devkit: a fresh process running `TrackingEval(config, results, "val", dir, version, dataroot)` (`init_s`: its
  NuScenes load, the submission, the ground truth, filters and tracks) and `main(render_curves=False)` (`main_s`).
Afterwards both metric files are compared (every number, the MOTP family within 1e-7).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")

TARGET_RATIO = 100.0
TARGET_RSS_FRACTION = 0.1
SPLIT = "val"


def devkit_child(dataroot: str, version: str, results: str, out_dir: str, init_only: bool = False) -> None:
    start = time.perf_counter()
    from nuscenes.eval.common.config import config_factory
    from nuscenes.eval.tracking.evaluate import TrackingEval

    imported = time.perf_counter()
    evaluation = TrackingEval(config_factory("tracking_nips_2019"), results, SPLIT, out_dir, version, dataroot,
                              verbose=False)
    initialised = time.perf_counter()
    if not init_only:
        evaluation.main(render_curves=False)
    done = time.perf_counter()
    print(json.dumps({"import_s": imported - start, "init_s": initialised - imported, "main_s": done - initialised,
                      "total_s": done - start}))
    sys.stdout.flush()
    os._exit(0)


def ours_child(out: str, results: str, out_dir: str) -> None:
    start = time.perf_counter()
    from nuparquet.evaluation.tracking import evaluate_tracking

    result = evaluate_tracking(out, results, out_dir, split=SPLIT, plots=False, overwrite=True)
    print(json.dumps({"total_s": time.perf_counter() - start, "eval_s": result.summary["eval_time"]}))
    sys.stdout.flush()
    os._exit(0)


def make_submission(out: Path, path: Path, boxes_per_sample: int, seed: int = 0) -> dict:
    """The submission of the module docstring, written to `path`; returns its counts."""
    import numpy as np
    import polars as pl

    import nuparquet
    from nuparquet.columns import to_numpy
    from nuparquet.evaluation.classes import CATEGORY_TO_TRACKING, TRACKING_NAMES
    from nuparquet.evaluation.splits import split_scene_names

    ds = nuparquet.open(out)
    names = split_scene_names(SPLIT)
    split_scenes = ds.scan("scenes").filter(pl.col("name").is_in(names)).select(pl.col("token").alias("scene_token"))
    samples = (ds.scan("tables/sample").join(split_scenes, on="scene_token", how="semi")
               .select("token").collect()["token"].to_list())
    ann = (ds.scan("annotations").filter(pl.col("scene_name").is_in(names))
           .with_columns(pl.col("category_name").cast(pl.String).replace_strict(CATEGORY_TO_TRACKING, default=None)
                         .alias("tracking_name"))
           .filter(pl.col("tracking_name").is_not_null())
           .select("sample_token", "instance_token", "tracking_name", "translation", "size", "rotation", "timestamp")
           .sort("instance_token", "timestamp").collect())
    ego = (ds.scan("frames").filter(pl.col("scene_name").is_in(names) & pl.col("is_key_frame")
                                    & (pl.col("channel").cast(pl.String) == "LIDAR_TOP"))
           .select("sample_token", "ego_translation").collect())
    ego_of = dict(zip(ego["sample_token"].to_list(), to_numpy(ego["ego_translation"], (3,)).tolist()))
    rng = np.random.default_rng(seed)
    n = ann.height
    instances, track_of = np.unique(ann["instance_token"].to_numpy().astype(str), return_inverse=True)
    track_of = track_of.reshape(-1)
    lost = rng.uniform(size=len(instances)) < 0.1
    switched = rng.uniform(size=len(instances)) < 0.05
    track_score = np.round(rng.uniform(0.05, 1.0, len(instances)), 2)
    within = np.arange(n) - np.searchsorted(track_of, track_of, "left")
    length = np.bincount(track_of)[track_of]
    kept = ~lost[track_of] & (rng.uniform(size=n) >= 0.1)
    ids = np.char.add(np.array([t[:12] for t in instances.tolist()])[track_of],
                      np.where(switched[track_of] & (within >= length // 2), "-b", ""))
    translation = to_numpy(ann["translation"], (3,), writable=True) + np.c_[rng.normal(0, 0.4, (n, 2)), np.zeros(n)]
    score = np.clip(track_score[track_of] + rng.normal(0, 0.03, n), 0.01, 1.0)
    size, rotation = to_numpy(ann["size"], (3,)), to_numpy(ann["rotation"], (4,))
    results: dict[str, list] = {token: [] for token in samples}
    for i in np.flatnonzero(kept):
        token = ann["sample_token"][int(i)]
        results[token].append({"sample_token": token, "translation": translation[i].tolist(), "size": size[i].tolist(),
                               "rotation": rotation[i].tolist(), "velocity": [0.0, 0.0], "tracking_id": str(ids[i]),
                               "tracking_name": ann["tracking_name"][int(i)], "tracking_score": float(score[i])})
    for s, (token, boxes) in enumerate(results.items()):
        boxes[:] = boxes[:boxes_per_sample]
        centre = np.array(ego_of[token])
        for j in range(max(boxes_per_sample - len(boxes), 0)):
            boxes.append({"sample_token": token, "translation": (centre + np.r_[rng.uniform(-50, 50, 2), 0]).tolist(),
                          "size": [1.8, 4.5, 1.6], "rotation": [1.0, 0.0, 0.0, 0.0], "velocity": [0.0, 0.0],
                          "tracking_id": f"fp-{s}-{j}", "tracking_name": TRACKING_NAMES[j % len(TRACKING_NAMES)],
                          "tracking_score": float(np.round(rng.uniform(0.0, 0.5), 2))})
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps({"meta": {"use_lidar": True, "use_camera": False, "use_radar": False, "use_map": False,
                                        "use_external": False}, "results": results}))
    os.replace(tmp, path)
    return {"samples": len(results), "boxes": sum(map(len, results.values()))}


def submission_path(out: Path, boxes_per_sample: int) -> Path:
    from bench_data import PARAMS, _params_match

    folder = out.parent / f"{out.name}-tracking-{boxes_per_sample}"
    dataset = json.loads((out / PARAMS).read_text()) if (out / PARAMS).is_file() else None
    params = {"tracking_submission": {"out": str(out.resolve()), "boxes_per_sample": boxes_per_sample,
                                      "dataset": dataset}}
    path = folder / "results.json"
    if path.is_file() and _params_match(folder, params):
        return path
    folder.mkdir(parents=True, exist_ok=True)
    counts = make_submission(out, path, boxes_per_sample)
    (folder / PARAMS).write_text(json.dumps({**params, **counts}) + "\n")
    return path


def _max_difference(a, b, path="") -> float:
    """The largest difference between two metric JSONs, the devkit's set-ordered detail keys compared as sets."""
    if isinstance(a, dict):
        if not isinstance(b, dict) or set(a) != set(b) or (not path.startswith("/details") and list(a) != list(b)):
            return math.inf
        return max([_max_difference(a[k], b[k], f"{path}/{k}") for k in a if k != "eval_time"], default=0.0)
    if isinstance(a, list):
        if not isinstance(b, list) or len(a) != len(b):
            return math.inf
        return max([_max_difference(x, y, path) for x, y in zip(a, b)], default=0.0)
    if isinstance(a, float) and isinstance(b, float):
        return 0.0 if (math.isnan(a) and math.isnan(b)) or a == b else abs(a - b)
    return 0.0 if a == b and type(a) is type(b) else math.inf


def run(repeats: int = 3, scenes: int = 100, boxes_per_sample: int = 60, ours_only_scenes: int | None = None) -> dict:
    import bench_data as datasets
    from harness import Row, log, megabytes, python_child, repeat, run_child, seconds, summarize, times

    root, out = datasets.scenes_root(scenes), datasets.scenes_out(scenes)
    results = submission_path(out, boxes_per_sample)
    counts = json.loads((results.parent / datasets.PARAMS).read_text())
    log(f"tracking: {counts['boxes']} boxes over {counts['samples']} samples of split {SPLIT} ({scenes} scenes)")
    with tempfile.TemporaryDirectory(prefix="bench-tracking-") as tmp:
        ours_dir, devkit_dir = Path(tmp) / "ours", Path(tmp) / "devkit"
        cmd = python_child(__file__, "--ours-child", out, results, ours_dir)
        ours = summarize(repeat(cmd, repeats, label="evaluate_tracking"), eval_s="eval_s")
        devkit_cmd = python_child(__file__, "--devkit-child", root, datasets.TRAINVAL_VERSION, results, devkit_dir)
        devkit_run = run_child(devkit_cmd, timeout_s=6 * 3600)
        log(f"  devkit {devkit_run.wall_s:.1f} s, {devkit_run.max_rss_mb:.0f} MiB")
        devkit = summarize([devkit_run], init_s="init_s", main_s="main_s", import_s="import_s")
        difference = {name: _max_difference(json.loads((ours_dir / f"metrics_{name}.json").read_text()),
                                            json.loads((devkit_dir / f"metrics_{name}.json").read_text()),
                                            f"/{name}")
                      for name in ("summary", "details")}
    ratio = devkit["wall_s"] / ours["wall_s"]
    rss_fraction = ours["max_rss_mb"] / devkit["max_rss_mb"]
    largest = max(difference.values())
    rows = [Row(
        id="tracking",
        benchmark=f"tracking evaluation, split {SPLIT} ({counts['samples']} samples, {counts['boxes']:,} predicted "
        f"boxes; {scenes}-scene set), end to end in a fresh process",
        ours=f"{seconds(ours['wall_s'])} ({seconds(ours['cpu_s'])} CPU; matching + metrics "
        f"{seconds(ours['eval_s'])}), {megabytes(ours['max_rss_mb'])} peak",
        reference=f"devkit {seconds(devkit['wall_s'])} (NuScenes + TrackingEval init {seconds(devkit['init_s'])}, "
        f"main {seconds(devkit['main_s'])}), {megabytes(devkit['max_rss_mb'])} peak",
        ratio=f"{times(ratio)}, {rss_fraction:.2f} of the memory",
        target=f"≥ {TARGET_RATIO:.0f}×, ≤ {TARGET_RSS_FRACTION:g} of the memory, same metrics",
        met=ratio >= TARGET_RATIO and rss_fraction <= TARGET_RSS_FRACTION and largest <= 1e-7,
        note=f"largest difference between the metric files {largest:.1e} (the MOTP family: the devkit's BLAS "
        "distances)")]
    result = {"name": "tracking", "scenes": scenes, "command": " ".join(map(str, cmd)),
              "devkit": {**devkit, "command": " ".join(map(str, devkit_cmd))}, "nuparquet": ours,
              "submission": counts, "max_difference": difference, "ratio": ratio, "rss_fraction": rss_fraction}
    if ours_only_scenes:
        big_out = datasets.scenes_out(ours_only_scenes)
        big_results = submission_path(big_out, boxes_per_sample)
        big_counts = json.loads((big_results.parent / datasets.PARAMS).read_text())
        with tempfile.TemporaryDirectory(prefix="bench-tracking-") as tmp:
            big_cmd = python_child(__file__, "--ours-child", big_out, big_results, Path(tmp) / "ours")
            big = summarize(repeat(big_cmd, repeats, label="evaluate_tracking (full)"), eval_s="eval_s")
            init_cmd = python_child(__file__, "--devkit-init-child", datasets.scenes_root(ours_only_scenes),
                                    datasets.TRAINVAL_VERSION, big_results, Path(tmp) / "devkit")
            init_run = run_child(init_cmd, timeout_s=3 * 3600)
            log(f"  devkit TrackingEval init (full) {init_run.wall_s:.1f} s, {init_run.max_rss_mb:.0f} MiB")
            init = summarize([init_run], init_s="init_s")
        rows.append(Row(
            id="tracking-full", benchmark=f"tracking evaluation, split {SPLIT} ({big_counts['samples']} samples, "
            f"{big_counts['boxes']:,} predicted boxes; {ours_only_scenes}-scene set), nuparquet alone",
            ours=f"{seconds(big['wall_s'])} ({seconds(big['cpu_s'])} CPU; matching + metrics "
            f"{seconds(big['eval_s'])}), {megabytes(big['max_rss_mb'])} peak",
            reference=f"devkit `TrackingEval` construction alone {seconds(init['wall_s'])} "
            f"({seconds(init['cpu_s'])} CPU), {megabytes(init['max_rss_mb'])} peak; its main not run (hours)",
            ratio=f"≥ {times(init['wall_s'] / big['wall_s'])}, ≤ {big['max_rss_mb'] / init['max_rss_mb']:.2f} of the "
            "memory", target=f"≥ {TARGET_RATIO:.0f}×, ≤ {TARGET_RSS_FRACTION:g} of the memory",
            met=big["max_rss_mb"] / init["max_rss_mb"] <= TARGET_RSS_FRACTION, note=""))
        result["full"] = {"scenes": ours_only_scenes, "nuparquet": big, "submission": big_counts,
                          "devkit_init": {**init, "command": " ".join(map(str, init_cmd))}}
    result["rows"] = rows
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=100, help="synthetic scenes of the compared set (default 100)")
    parser.add_argument("--boxes-per-sample", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--ours-only-scenes", type=int, default=None,
                        help="also time nuparquet alone on a set this large (850: trainval scale)")
    parser.add_argument("--devkit-child", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--ours-child", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--devkit-init-child", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.devkit_child:
        devkit_child(*args.devkit_child)
        return
    if args.devkit_init_child:
        devkit_child(*args.devkit_init_child, init_only=True)
        return
    if args.ours_child:
        ours_child(*args.ours_child)
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes, args.boxes_per_sample, args.ours_only_scenes))


if __name__ == "__main__":
    main()
