"""Row 1: convert the trainval-scale metadata (all datasets) vs the devkit's bare load.

    .venv/bin/python benchmarks/bench_convert.py [--repeats 3] [--devkit-repeats 3]

nuparquet: `nuparquet convert .bench-cache/trainval --version v1.0-trainval --out .bench-cache/convert-run/out
--quiet`, a fresh process per repeat into an empty target (deleted after each run): wall time and peak RSS of
the whole process. Reference: `NuScenes(version, dataroot)` in a fresh process (`devkit_reference.py`), the
process wall time up to the end of construction (interpreter start-up + import + load and index).
Targets (2 cores): ≤ 60 s, ≤ 4 GB peak RSS, faster than the devkit's load.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

TARGET_WALL_S = 60.0
TARGET_RSS_MB = 4 * 1024


def run(repeats: int = 3, devkit_repeats: int = 3) -> dict:
    import bench_data as datasets
    import devkit_reference
    from bench_project_scene import first_scene
    from harness import Row, log, megabytes, run_child, seconds, summarize, times

    root = datasets.trainval_root()
    work = datasets.CACHE / "convert-run"
    target = work / "out"
    cmd = [*datasets.NUPARQUET, "convert", str(root), "--version", datasets.TRAINVAL_VERSION, "--out", str(target),
           "--quiet"]
    log("row 1: convert trainval-scale metadata")
    runs, out_bytes = [], 0
    for i in range(repeats):
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir(parents=True)
        run = run_child(cmd)
        runs.append(run)
        out_bytes = sum(p.stat().st_size for p in target.rglob("*") if p.is_file())
        log(f"  nuparquet convert [{i + 1}/{repeats}] {run.wall_s:.1f} s, {run.max_rss_mb:.0f} MiB")
    shutil.rmtree(work, ignore_errors=True)
    ours = summarize(runs)
    json_bytes = sum(p.stat().st_size for p in (root / datasets.TRAINVAL_VERSION).glob("*.json"))

    out = datasets.trainval_out()
    devkit = devkit_reference.measure(root, datasets.TRAINVAL_VERSION, first_scene(out), out, devkit_repeats)
    speedup = devkit["load_wall_s"] / ours["wall_s"]
    rss_ratio = devkit["max_rss_mb"] / ours["max_rss_mb"]
    met = ours["wall_s"] <= TARGET_WALL_S and ours["max_rss_mb"] <= TARGET_RSS_MB and speedup > 1
    row = Row(
        id="1",
        benchmark=f"convert trainval-scale metadata, all datasets ({json_bytes / 1e9:.2f} GB JSON -> "
        f"{out_bytes / 1e9:.2f} GB Parquet)",
        ours=f"{seconds(ours['wall_s'])}, {megabytes(ours['max_rss_mb'])} peak",
        reference=f"devkit load {seconds(devkit['load_wall_s'])}, {megabytes(devkit['max_rss_mb'])} peak",
        ratio=f"speed {times(speedup)}, peak RSS {times(rss_ratio)} smaller",
        target=f"≤ {TARGET_WALL_S:.0f} s, ≤ {TARGET_RSS_MB / 1024:.0f} GB, faster than devkit load",
        met=met,
    )
    return {"name": "convert", "command": " ".join(map(str, cmd)), "nuparquet": ours, "json_bytes": json_bytes,
            "parquet_bytes": out_bytes,
            "devkit": {k: devkit[k] for k in ("command", "repeats", "load_wall_s", "load_walls_s", "max_rss_mb",
                                              "cpu_s", "import_s", "construct_s")},
            "speedup": speedup, "rss_ratio": rss_ratio, "rows": [row]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--devkit-repeats", type=int, default=3)
    args = parser.parse_args()
    from harness import report_alone

    report_alone(run(args.repeats, args.devkit_repeats))


if __name__ == "__main__":
    main()
