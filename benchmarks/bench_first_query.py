"""Row 2: open + first query in a fresh process — annotations per category over all ~1.17M annotations.

    .venv/bin/python benchmarks/bench_first_query.py [--repeats 5] [--devkit-repeats 3]

nuparquet, a fresh process per repeat (whole-process wall time and peak RSS, interpreter start-up included):

    import nuparquet
    ds = nuparquet.open(OUT)
    ds.scan("annotations").group_by("category_name").len().collect()

Reference (`devkit_reference.py`, same process as rows 1 and 3): interpreter start-up + import +
`NuScenes(version, dataroot)` + `Counter(a["category_name"] for a in nusc.sample_annotation)`. The counts
are checked equal. Targets: ≤ 0.15 s and ≤ 100 MB peak RSS; ≥ 100× faster.

Floor (`--floor-child`, same repeats): a process that imports polars alone and runs the same query over the
annotation files with `pl.scan_parquet` (no nuparquet import, no manifest): what the interpreter and polars
cost before nuparquet adds anything.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

TARGET_WALL_S = 0.15
TARGET_RSS_MB = 100.0
TARGET_RATIO = 100.0


def child(out: str) -> None:
    """The measured program: nothing but the import, the open and the query (and printing the counts)."""
    start = time.perf_counter()
    import nuparquet

    ds = nuparquet.open(out)
    counts = ds.scan("annotations").group_by("category_name").len().collect()
    end = time.perf_counter()
    print(json.dumps({"in_process_s": end - start,
                      "counts": {str(k): int(v) for k, v in counts.iter_rows()}}))


def floor_child(out: str) -> None:
    """The floor: polars alone over the same files."""
    start = time.perf_counter()
    import polars as pl

    counts = pl.scan_parquet(f"{out}/annotations/*.parquet").group_by("category_name").len().collect()
    print(json.dumps({"in_process_s": time.perf_counter() - start, "categories": counts.height}))


def run(repeats: int = 5, devkit_repeats: int = 3) -> dict:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_data as datasets
    import devkit_reference
    from bench_project_scene import first_scene
    from harness import Row, log, megabytes, python_child, repeat, seconds, summarize, times

    out = datasets.trainval_out()
    log("row 2: open + first query (annotations per category)")
    cmd = python_child(__file__, "--child", out)
    runs = repeat(cmd, repeats, label="nuparquet open + query")
    ours = summarize(runs, in_process_s="in_process_s")
    floor_cmd = python_child(__file__, "--floor-child", out)
    floor = summarize(repeat(floor_cmd, repeats, label="polars alone, same query"), in_process_s="in_process_s")
    devkit = devkit_reference.measure(datasets.trainval_root(), datasets.TRAINVAL_VERSION, first_scene(out), out,
                                      devkit_repeats)
    same_counts = runs[0].report["counts"] == devkit["counts"]
    speedup = devkit["count_wall_s"] / ours["wall_s"]
    met = ours["wall_s"] <= TARGET_WALL_S and ours["max_rss_mb"] <= TARGET_RSS_MB and speedup >= TARGET_RATIO
    row = Row(
        id="2",
        benchmark=f"open + first query in a fresh process: annotations per category "
        f"({sum(devkit['counts'].values()):,} annotations)",
        ours=f"{seconds(ours['wall_s'])}, {megabytes(ours['max_rss_mb'])} peak (in-process "
        f"{seconds(ours['in_process_s'])})",
        reference=f"devkit load + count loop {seconds(devkit['count_wall_s'])}, {megabytes(devkit['max_rss_mb'])} peak "
        f"(count loop alone {seconds(devkit['count_s'])})",
        ratio=f"speed {times(speedup)}, peak RSS {times(devkit['max_rss_mb'] / ours['max_rss_mb'])} smaller",
        target=f"≤ {TARGET_WALL_S} s, ≤ {TARGET_RSS_MB:.0f} MB, ≥ {TARGET_RATIO:.0f}×",
        met=met and same_counts,
        note=f"row 2 check: per-category counts equal to the devkit's: {same_counts}; floor (polars alone, the "
        f"same query): {seconds(floor['wall_s'])}, {megabytes(floor['max_rss_mb'])} peak",
    )
    return {"name": "first_query", "command": " ".join(map(str, cmd)), "nuparquet": ours,
            "devkit": {k: devkit[k] for k in ("count_wall_s", "count_s", "max_rss_mb")}, "same_counts": same_counts,
            "floor": {"command": " ".join(map(str, floor_cmd)), **floor},
            "speedup": speedup, "rows": [row]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--devkit-repeats", type=int, default=3)
    parser.add_argument("--child", metavar="OUT", help=argparse.SUPPRESS)
    parser.add_argument("--floor-child", metavar="OUT", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return
    if args.floor_child:
        floor_child(args.floor_child)
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from harness import report_alone

    report_alone(run(args.repeats, args.devkit_repeats))


if __name__ == "__main__":
    main()
