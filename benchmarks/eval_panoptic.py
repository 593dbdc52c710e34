"""Panoptic evaluation: nuparquet's `evaluate_panoptic` end to end vs the devkit's `NuScenesPanopticEval` end to
end (its own `NuScenes` load) and vs the floor of reading the label files, each in a fresh process.

    .venv/bin/python benchmarks/eval_panoptic.py [--scenes 16] [--repeats 3]

Data: a synthetic set with lidar and its Panoptic nuScenes labels (`nuparquet synth --with-lidar`, `--scenes N` x
40 samples, v1.0-trainval; ~5,000 points a frame), converted without its points (the ground truth is read from
the label files, as the devkit reads it), evaluated on split val (its scenes whose names are in the devkit's val
list); a submission made from the ground truth with the tests' seeded perturbations
(tests/evaluation/panoptic_submissions.py: instances split, merged, relabelled, switched; cached beside the set).
Both tasks, segmentation and tracking:

- nuparquet: a fresh process running `evaluate_panoptic(OUT, RESULTS, DIR, split="val", task=...)` (open, read
  the submission, the ground truth, evaluate, write the result file and the two tables): wall time, peak RSS,
  CPU, and its own time after the imports (`eval_s`).
- devkit: a fresh process running `NuScenes(version, dataroot)` (`load_s`) and `NuScenesPanopticEval(...)
  .evaluate()` (`eval_s`), the split list cut to the scenes the set holds (the devkit fails on a missing one).
- floor: a fresh process importing numpy and `np.load`ing every ground-truth and prediction file of the split
  (`read_s`: the loop alone).
Afterwards both result files are compared (every number exactly, the daggers within 1e-12: docs/CONTRACTS.md).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_DEVKIT_RATIO = 10.0
TARGET_FLOOR_RATIO = 1.5
TARGET_RSS_FRACTION = 0.1
SPLIT = "val"
VERSION = "v1.0-trainval"
DEVKIT_TASK = {"panoptic": "segmentation", "panoptic-tracking": "tracking"}


def devkit_child(dataroot: str, results: str, task: str, out_dir: str) -> None:
    start = time.perf_counter()
    from nuscenes.eval.lidarseg import utils
    from nuscenes.eval.panoptic import evaluate
    from nuscenes.nuscenes import NuScenes
    from nuscenes.utils.splits import create_splits_scenes

    imported = time.perf_counter()
    nusc = NuScenes(version=VERSION, dataroot=dataroot, verbose=False)
    loaded = time.perf_counter()
    present = {scene["name"] for scene in nusc.scene}
    names = [name for name in create_splits_scenes()[SPLIT] if name in present]
    for module in (utils, evaluate):
        module.create_splits_scenes = lambda verbose=False: {SPLIT: names}
    evaluate.NuScenesPanopticEval(nusc, results, SPLIT, task, 15, out_dir=out_dir).evaluate()
    done = time.perf_counter()
    print(json.dumps({"import_s": imported - start, "load_s": loaded - imported, "eval_s": done - loaded,
                      "total_s": done - start}))
    sys.stdout.flush()
    os._exit(0)


def ours_child(out: str, results: str, task: str, out_dir: str) -> None:
    start = time.perf_counter()
    from nuparquet.evaluation.panoptic import evaluate_panoptic

    imported = time.perf_counter()
    result = evaluate_panoptic(out, results, out_dir, split=SPLIT, task=task, overwrite=True)
    done = time.perf_counter()
    print(json.dumps({"import_s": imported - start, "eval_s": done - imported, "total_s": done - start,
                      "frames": len(result.frames)}))
    sys.stdout.flush()
    os._exit(0)


def floor_child(listing: str) -> None:
    start = time.perf_counter()
    import numpy as np

    paths = json.loads(Path(listing).read_text())
    imported = time.perf_counter()
    points = 0
    for gt, pred in paths:
        points += len(np.load(gt)["data"]) + len(np.load(pred)["data"])
    done = time.perf_counter()
    print(json.dumps({"import_s": imported - start, "read_s": done - imported, "total_s": done - start,
                      "points": points}))
    sys.stdout.flush()
    os._exit(0)


def dataset(scenes: int) -> tuple[Path, Path]:
    """(dataroot, OUT) of the labelled set, built once into the benchmark cache."""
    from bench_data import CACHE, NUPARQUET, PARAMS, _params_match
    from harness import log

    root, out = CACHE / f"panoptic-{scenes}", CACHE / f"panoptic-{scenes}-out"
    params = {"synth": {"scenes": scenes, "samples_per_scene": 40, "version": VERSION, "with_lidar": True,
                        "can_bus": False, "seed": 0}}
    if not ((root / VERSION / "panoptic.json").is_file() and _params_match(root, params)):
        log(f"building {root} ({scenes} scenes x 40 samples with lidar and labels) ...")
        subprocess.run([*NUPARQUET, "synth", str(root), "--scenes", str(scenes), "--samples-per-scene", "40",
                        "--with-lidar", "--no-can-bus", "--version", VERSION, "--quiet"], check=True)
        (root / PARAMS).write_text(json.dumps(params) + "\n")
    converted = {"convert": {"dataroot": str(root.resolve()), "synth": params}}
    if not ((out / "manifest.json").is_file() and _params_match(out, converted)):
        log(f"converting {root} -> {out} ...")
        subprocess.run([*NUPARQUET, "convert", str(root), "--version", VERSION, "--out", str(out), "--overwrite",
                        "--quiet"], check=True)
        (out / PARAMS).write_text(json.dumps(converted) + "\n")
    return root, out


def submission(root: Path) -> Path:
    """The perturbed submission (seed 1) for every keyframe LIDAR_TOP of the set, cached."""
    from bench_data import PARAMS, _params_match

    folder = root.parent / f"{root.name}-panoptic-results"
    params = {"panoptic_submission": {"root": str(root.resolve()), "seed": 1}}
    if (folder / SPLIT / "submission.json").is_file() and _params_match(folder, params):
        return folder
    import shutil

    from nuscenes.nuscenes import NuScenes

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "evaluation"))
    import panoptic_submissions

    if folder.exists():
        shutil.rmtree(folder)
    nusc = NuScenes(version=VERSION, dataroot=str(root), verbose=False)
    panoptic_submissions.write(nusc, folder, 1, split=SPLIT)
    (folder / PARAMS).write_text(json.dumps(params) + "\n")
    return folder


def _compare(ours: dict, theirs: dict) -> float:
    """The largest difference between the two result files (inf: other keys or order); daggers included."""
    if isinstance(ours, dict):
        if not isinstance(theirs, dict) or list(ours) != list(theirs):
            return math.inf
        return max((_compare(ours[k], theirs[k]) for k in ours), default=0.0)
    if math.isnan(ours) and math.isnan(theirs):
        return 0.0
    return abs(ours - theirs) / max(abs(theirs), 1e-300) if ours != theirs else 0.0


def _exact_but_daggers(ours: dict, theirs: dict) -> bool:
    strip = {task: {name: {k: v for k, v in values.items() if not k.endswith("_dagger")}
                    for name, values in part.items()} for task, part in ours.items()}
    strip_theirs = {task: {name: {k: v for k, v in values.items() if not k.endswith("_dagger")}
                           for name, values in part.items()} for task, part in theirs.items()}
    return json.dumps(strip) == json.dumps(strip_theirs)


def run(repeats: int = 3, scenes: int = 16) -> dict:
    from harness import Row, log, megabytes, python_child, repeat, run_child, seconds, summarize, times

    import nuparquet
    from nuparquet.evaluation.segmentation.run import split_frames

    root, out = dataset(scenes)
    results = submission(root)
    frames, _ = split_frames(nuparquet.open(out), SPLIT)
    gt_files = {rec["sample_data_token"]: rec["filename"]
                for rec in json.loads((root / VERSION / "panoptic.json").read_text())}
    rows, measured = [], {}
    with tempfile.TemporaryDirectory(prefix="bench-panoptic-") as tmp:
        listing = Path(tmp) / "files.json"
        listing.write_text(json.dumps([[str(root / gt_files[token]),
                                        str(results / "panoptic" / SPLIT / f"{token}_panoptic.npz")]
                                       for token in frames["token"].to_list()]))
        floor = summarize(repeat(python_child(__file__, "--floor-child", listing), repeats, label="floor"),
                          read_s="read_s", import_s="import_s")
        log(f"panoptic: {frames.height} frames of split {SPLIT} ({scenes}-scene set); floor read "
            f"{floor['read_s']:.3f} s")
        for task, devkit_task in DEVKIT_TASK.items():
            ours_dir, devkit_dir = Path(tmp) / f"ours-{task}", Path(tmp) / f"devkit-{task}"
            cmd = python_child(__file__, "--ours-child", out, results, task, ours_dir)
            ours = summarize(repeat(cmd, repeats, label=f"evaluate_panoptic {task}"), eval_s="eval_s",
                             import_s="import_s")
            devkit_cmd = python_child(__file__, "--devkit-child", root, results, devkit_task, devkit_dir)
            devkit_run = run_child(devkit_cmd, timeout_s=3 * 3600)
            log(f"  devkit {devkit_task} {devkit_run.wall_s:.1f} s, {devkit_run.max_rss_mb:.0f} MiB")
            devkit = summarize([devkit_run], load_s="load_s", eval_s="eval_s")
            name = f"{devkit_task}-result.json"
            mine, theirs = (json.loads((d / name).read_text()) for d in (ours_dir, devkit_dir))
            exact, largest = _exact_but_daggers(mine, theirs), _compare(mine, theirs)
            ratio = devkit["wall_s"] / ours["wall_s"]
            floor_ratio = ours["wall_s"] / floor["wall_s"]
            eval_floor_ratio = ours["eval_s"] / floor["read_s"]
            rss_fraction = ours["max_rss_mb"] / devkit["max_rss_mb"]
            rows.append(Row(
                id=task, benchmark=f"{task} evaluation, split {SPLIT} ({frames.height} lidar frames; {scenes}-scene "
                "set), end to end in a fresh process",
                ours=f"{seconds(ours['wall_s'])} ({seconds(ours['cpu_s'])} CPU; after imports "
                f"{seconds(ours['eval_s'])}), {megabytes(ours['max_rss_mb'])} peak",
                reference=f"devkit {seconds(devkit['wall_s'])} ({seconds(devkit['cpu_s'])} CPU; NuScenes "
                f"{seconds(devkit['load_s'])}, evaluate {seconds(devkit['eval_s'])}), "
                f"{megabytes(devkit['max_rss_mb'])} peak; floor (np.load of the {2 * frames.height} files) "
                f"{seconds(floor['wall_s'])} ({seconds(floor['cpu_s'])} CPU), its loop {seconds(floor['read_s'])}",
                ratio=f"{times(ratio)} the devkit ({times(devkit['cpu_s'] / ours['cpu_s'])} CPU), "
                f"{rss_fraction:.2f} of its memory; {floor_ratio:.2f}× the floor end to end "
                f"({ours['cpu_s'] / floor['cpu_s']:.2f}× CPU), {eval_floor_ratio:.2f}× its loop after imports",
                target=f"≥ {TARGET_DEVKIT_RATIO:.0f}× the devkit, ≤ {TARGET_FLOOR_RATIO:g}× the floor, ≤ "
                f"{TARGET_RSS_FRACTION:g} of the memory, same metrics",
                met=(ratio >= TARGET_DEVKIT_RATIO and floor_ratio <= TARGET_FLOOR_RATIO
                     and rss_fraction <= TARGET_RSS_FRACTION and exact and largest <= 1e-12),
                note=f"{task}: result files equal but for the daggers' last bits: {exact}; largest relative "
                f"difference {largest:.1e}"))
            measured[task] = {"command": " ".join(map(str, cmd)), "nuparquet": ours,
                              "devkit": {**devkit, "command": " ".join(map(str, devkit_cmd))}, "exact": exact,
                              "largest_difference": largest, "ratio": ratio, "floor_ratio": floor_ratio,
                              "rss_fraction": rss_fraction}
    return {"name": "eval_panoptic", "scenes": scenes, "frames": frames.height, "floor": floor, **measured,
            "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=16, help="synthetic scenes with lidar (default 16)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--devkit-child", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--ours-child", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--floor-child", nargs=1, help=argparse.SUPPRESS)
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # this checkout's nuparquet, in every child
    if args.devkit_child:
        devkit_child(*args.devkit_child)
        return
    if args.ours_child:
        ours_child(*args.ours_child)
        return
    if args.floor_child:
        floor_child(*args.floor_child)
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes))


if __name__ == "__main__":
    main()
