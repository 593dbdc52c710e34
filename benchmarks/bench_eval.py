"""Detection evaluation: `nuparquet eval` end to end vs the devkit's `NuScenes` load + `DetectionEval.main`.

    .venv/bin/python benchmarks/bench_eval.py [--scenes 850] [--boxes-per-sample 50] [--repeats 3] [--devkit-repeats 1]

Data: the trainval-scale synthetic set (`bench_data.py`, v1.0-trainval; `--scenes N` builds a smaller one of the
same shape), evaluated on split val (its scenes whose names are in the devkit's val list), with a submission made
from its ground truth (cached beside the set): every annotation of a detection class shifted (0.5 m sd), rescaled
and turned, a tenth of them missed, a tenth given another attribute, scores on a 0.01 grid, and false positives
around the ego vehicle up to `--boxes-per-sample` boxes per sample.

- nuparquet: a fresh process running `nuparquet eval OUT --results R --split val --out DIR --no-plots --quiet`
  (open, read the submission, load the ground truth, evaluate, write the metric files and the predictions/ and
  ground_truth/ datasets): wall time, peak RSS, CPU.
- devkit, in a fresh process: `NuScenes(version, dataroot)` (`load_s`), `DetectionEval(...)` (`init_s`: the
  submission read, `load_gt`, centre distances and filters), `main(render_curves=False)` (`main_s`; its
  `eval_time`, the matching and the metrics, is reported as `match_s`): the split between loading and matching.
Afterwards both metrics_summary.json files are compared (every number within 1e-9).
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

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit imports pyplot; never open a window

TARGET_RATIO = 100.0
TARGET_RSS_FRACTION = 0.1
SPLIT = "val"


def devkit_child(dataroot: str, version: str, results: str, out_dir: str) -> None:
    start = time.perf_counter()
    from nuscenes.eval.detection.config import config_factory
    from nuscenes.eval.detection.evaluate import DetectionEval
    from nuscenes.nuscenes import NuScenes

    imported = time.perf_counter()
    nusc = NuScenes(version=version, dataroot=dataroot, verbose=False)
    loaded = time.perf_counter()
    evaluation = DetectionEval(nusc, config_factory("detection_cvpr_2019"), results, SPLIT, out_dir, verbose=False)
    initialised = time.perf_counter()
    summary = evaluation.main(plot_examples=0, render_curves=False)
    done = time.perf_counter()
    print(json.dumps({"import_s": imported - start, "load_s": loaded - imported, "init_s": initialised - loaded,
                      "main_s": done - initialised, "match_s": summary["eval_time"], "total_s": done - start,
                      "samples": len(evaluation.sample_tokens)}))
    sys.stdout.flush()
    os._exit(0)  # not timed, but the process would spend seconds freeing the devkit's dicts


def make_submission(out: Path, path: Path, boxes_per_sample: int, seed: int = 0) -> dict:
    """The perturbed submission described in the module docstring, written to `path`; returns its counts."""
    import numpy as np
    import polars as pl

    import nuparquet
    from nuparquet.columns import to_numpy
    from nuparquet.evaluation.classes import ATTRIBUTE_NAMES, CATEGORY_TO_DETECTION, DETECTION_NAMES
    from nuparquet.evaluation.splits import split_scene_names

    ds = nuparquet.open(out)
    names = split_scene_names(SPLIT)
    split_scenes = ds.scan("scenes").filter(pl.col("name").is_in(names)).select(pl.col("token").alias("scene_token"))
    samples = (ds.scan("tables/sample").join(split_scenes, on="scene_token", how="semi")
               .select("token").collect()["token"].to_list())
    ann = (ds.scan("annotations").filter(pl.col("scene_name").is_in(names))
           .with_columns(pl.col("category_name").cast(pl.String).replace_strict(CATEGORY_TO_DETECTION, default=None)
                         .alias("detection_name"))
           .filter(pl.col("detection_name").is_not_null())
           .select("sample_token", "detection_name", "translation", "size", "rotation", "velocity",
                   pl.col("attribute_names").list.first().fill_null("").alias("attribute_name"))
           .collect())
    ego = (ds.scan("frames").filter(pl.col("scene_name").is_in(names) & pl.col("is_key_frame")
                                    & (pl.col("channel").cast(pl.String) == "LIDAR_TOP"))
           .select("sample_token", "ego_translation").collect())
    ego_of = dict(zip(ego["sample_token"].to_list(), to_numpy(ego["ego_translation"], (3,)).tolist()))
    rng = np.random.default_rng(seed)
    n = ann.height
    kept = rng.uniform(size=n) >= 0.1
    translation = to_numpy(ann["translation"], (3,), writable=True) + np.c_[rng.normal(0, 0.5, (n, 2)), np.zeros(n)]
    size = to_numpy(ann["size"], (3,), writable=True) * rng.uniform(0.85, 1.15, (n, 3))
    yaw = rng.normal(0, 0.2, n)
    q = to_numpy(ann["rotation"], (4,), writable=True)
    turn = np.c_[np.cos(yaw / 2), np.zeros((n, 2)), np.sin(yaw / 2)]  # q * rotation about z
    rotation = np.c_[q[:, 0] * turn[:, 0] - q[:, 3] * turn[:, 3], q[:, 1] * turn[:, 0] + q[:, 2] * turn[:, 3],
                     q[:, 2] * turn[:, 0] - q[:, 1] * turn[:, 3], q[:, 3] * turn[:, 0] + q[:, 0] * turn[:, 3]]
    velocity = np.nan_to_num(to_numpy(ann["velocity"], (3,))[:, :2]) + rng.normal(0, 0.3, (n, 2))
    attribute = np.where(rng.uniform(size=n) < 0.1, rng.choice(ATTRIBUTE_NAMES, n),
                         ann["attribute_name"].to_numpy().astype(object))
    score = np.round(rng.uniform(0.05, 1.0, n), 2)
    results: dict[str, list] = {token: [] for token in samples}
    for i in np.flatnonzero(kept):
        token = ann["sample_token"][int(i)]
        results[token].append({"sample_token": token, "translation": translation[i].tolist(), "size": size[i].tolist(),
                               "rotation": rotation[i].tolist(), "velocity": velocity[i].tolist(),
                               "detection_name": ann["detection_name"][int(i)], "detection_score": float(score[i]),
                               "attribute_name": str(attribute[i])})
    for token, boxes in results.items():
        boxes[:] = boxes[:boxes_per_sample]
        extra = boxes_per_sample - len(boxes)
        centre = np.array(ego_of[token])
        for j in range(max(extra, 0)):
            boxes.append({"sample_token": token, "translation": (centre + np.r_[rng.uniform(-50, 50, 2), 0]).tolist(),
                          "size": rng.uniform(0.5, 4.0, 3).tolist(), "rotation": [1.0, 0.0, 0.0, 0.0],
                          "velocity": [0.0, 0.0], "detection_name": str(DETECTION_NAMES[j % len(DETECTION_NAMES)]),
                          "detection_score": float(np.round(rng.uniform(0.0, 0.6), 2)), "attribute_name": ""})
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps({"meta": {"use_lidar": True, "use_camera": False, "use_radar": False, "use_map": False,
                                        "use_external": False}, "results": results}))
    os.replace(tmp, path)
    return {"samples": len(results), "boxes": sum(map(len, results.values()))}


def submission_path(out: Path, boxes_per_sample: int) -> Path:
    """The cached submission of dataset `out` (rebuilt when the dataset or the parameters change)."""
    from bench_data import PARAMS, _params_match

    folder = out.parent / f"{out.name}-eval-{boxes_per_sample}"
    dataset = json.loads((out / PARAMS).read_text()) if (out / PARAMS).is_file() else None
    params = {"eval_submission": {"out": str(out.resolve()), "boxes_per_sample": boxes_per_sample,
                                  "dataset": dataset}}
    path = folder / "results.json"
    if path.is_file() and _params_match(folder, params):
        return path
    folder.mkdir(parents=True, exist_ok=True)
    counts = make_submission(out, path, boxes_per_sample)
    (folder / PARAMS).write_text(json.dumps({**params, **counts}) + "\n")
    return path


def _max_difference(a, b) -> float:
    """The largest difference between two metric JSONs (inf for a structural difference)."""
    if isinstance(a, dict):
        if not isinstance(b, dict) or list(a) != list(b):
            return math.inf
        return max([_max_difference(a[k], b[k]) for k in a if k != "eval_time"], default=0.0)
    if isinstance(a, list):
        if not isinstance(b, list) or len(a) != len(b):
            return math.inf
        return max([_max_difference(x, y) for x, y in zip(a, b)], default=0.0)
    if isinstance(a, float) and isinstance(b, float):
        return 0.0 if (math.isnan(a) and math.isnan(b)) or a == b else abs(a - b)
    return 0.0 if a == b else math.inf


def run(repeats: int = 3, devkit_repeats: int = 1, scenes: int | None = None, boxes_per_sample: int = 50) -> dict:
    import bench_data as datasets
    from harness import Row, log, megabytes, python_child, repeat, run_child, seconds, summarize, times

    scenes = scenes or datasets.TRAINVAL_SCENES
    root, out = datasets.scenes_root(scenes), datasets.scenes_out(scenes)
    results = submission_path(out, boxes_per_sample)
    counts = json.loads((results.parent / datasets.PARAMS).read_text())
    log(f"eval: {counts['boxes']} boxes over {counts['samples']} samples of split {SPLIT}")
    with tempfile.TemporaryDirectory(prefix="bench-eval-") as tmp:
        ours_dir, devkit_dir = Path(tmp) / "ours", Path(tmp) / "devkit"
        cmd = [*datasets.NUPARQUET, "eval", str(out), "--results", str(results), "--split", SPLIT, "--out",
               str(ours_dir), "--no-plots", "--overwrite", "--quiet"]
        ours = summarize(repeat(cmd, repeats, label="nuparquet eval"))
        devkit_cmd = python_child(__file__, "--devkit-child", root, datasets.TRAINVAL_VERSION, results, devkit_dir)
        devkit_runs = []
        for i in range(devkit_repeats):
            devkit_runs.append(run_child(devkit_cmd, timeout_s=4 * 3600))
            log(f"  devkit [{i + 1}/{devkit_repeats}] {devkit_runs[-1].wall_s:.1f} s, "
                f"{devkit_runs[-1].max_rss_mb:.0f} MiB")
        devkit = summarize(devkit_runs, load_s="load_s", init_s="init_s", match_s="match_s", main_s="main_s",
                           import_s="import_s")
        difference = max(_max_difference(json.loads((ours_dir / name).read_text()),
                                          json.loads((devkit_dir / name).read_text()))
                         for name in ("metrics_summary.json", "metrics_details.json"))
    ratio = devkit["wall_s"] / ours["wall_s"]
    rss_fraction = ours["max_rss_mb"] / devkit["max_rss_mb"]
    row = Row(
        id="eval",
        benchmark=f"detection evaluation, split {SPLIT} ({counts['samples']} samples, {counts['boxes']:,} predicted "
        f"boxes; {scenes}-scene set), end to end in a fresh process",
        ours=f"{seconds(ours['wall_s'])} ({seconds(ours['cpu_s'])} CPU), {megabytes(ours['max_rss_mb'])} peak",
        reference=f"devkit {seconds(devkit['wall_s'])} (NuScenes {seconds(devkit['load_s'])}, DetectionEval init "
        f"{seconds(devkit['init_s'])}, matching + metrics {seconds(devkit['match_s'])}), "
        f"{megabytes(devkit['max_rss_mb'])} peak",
        ratio=f"{times(ratio)}, {rss_fraction:.2f} of the memory",
        target=f"≥ {TARGET_RATIO:.0f}×, ≤ {TARGET_RSS_FRACTION:g} of the memory, same metrics",
        met=ratio >= TARGET_RATIO and rss_fraction <= TARGET_RSS_FRACTION and difference <= 1e-9,
        note=f"eval check: largest difference between the two metric files {difference:.1e}",
    )
    return {"name": "eval", "scenes": scenes, "command": " ".join(map(str, cmd)),
            "devkit": {**devkit, "command": " ".join(map(str, devkit_cmd))}, "nuparquet": ours,
            "submission": counts, "max_difference": difference, "ratio": ratio, "rss_fraction": rss_fraction,
            "rows": [row]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=None, help="synthetic scenes (default: trainval scale, 850)")
    parser.add_argument("--boxes-per-sample", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--devkit-repeats", type=int, default=1,
                        help="devkit processes (minutes and ~10 GB each at trainval scale; default 1)")
    parser.add_argument("--devkit-child", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.devkit_child:
        devkit_child(*args.devkit_child)
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from harness import report_alone

    report_alone(run(args.repeats, args.devkit_repeats, args.scenes, args.boxes_per_sample))


if __name__ == "__main__":
    main()
