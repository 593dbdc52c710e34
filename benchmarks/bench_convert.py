"""Row 1: convert the trainval-scale metadata (every derived dataset) vs DuckDB copying the same JSON to Parquet.

    .venv/bin/python benchmarks/bench_convert.py [--repeats 3] [--devkit-repeats 0]

Per repeat, one fresh process each, interleaved (so a busy moment hits all three alike), into empty targets:
- nuparquet: `nuparquet convert .bench-cache/trainval --version v1.0-trainval --out ... --no-map --quiet`: the 13
  metadata tables (typed, lossless, checked) and every dataset derived from them (frames, annotations, scenes,
  instances): the same input as the floor.
- nuparquet with the map expansion too (the default, `map/` GeoParquet): the synthetic trainval has one map
  expansion per location grown along its 850 scenes' roads, JSON the floor does not read.
- the floor (`duckdb_floor.py`): `COPY (SELECT * FROM read_json(...)) TO ... (FORMAT parquet)` per table, the
  same 2 threads, no checks, no joins.
Wall time and peak RSS of each whole process; medians. Optionally (`--devkit-repeats N`) the devkit's bare
`NuScenes(version, dataroot)` load (`devkit_reference.py`). Targets (2 cores): ≤ 1.2x the floor, ≤ 3 GB peak.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

TARGET_RATIO = 1.2
TARGET_RSS_MB = 3 * 1024


def run(repeats: int = 3, devkit_repeats: int = 0) -> dict:
    import bench_data as datasets
    from harness import PYTHON, Row, log, megabytes, run_child, seconds, summarize, times

    root = datasets.trainval_root()
    work = datasets.CACHE / "convert-run"
    target = work / "out"
    cmd = [*datasets.NUPARQUET, "convert", str(root), "--version", datasets.TRAINVAL_VERSION, "--out", str(target),
           "--quiet"]
    floor_cmd = [PYTHON, str(Path(__file__).resolve().parent / "duckdb_floor.py"), str(root),
                 datasets.TRAINVAL_VERSION, "--threads", "2"]
    log("row 1: convert trainval-scale metadata")
    runs: dict[str, list] = {"metadata": [], "with_map": [], "floor": []}
    out_bytes = {}
    for i in range(repeats):
        for label, command in (("metadata", [*cmd, "--no-map"]), ("floor", floor_cmd), ("with_map", cmd)):
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir(parents=True)
            run = run_child(command)
            runs[label].append(run)
            if label != "floor":
                out_bytes[label] = sum(p.stat().st_size for p in target.rglob("*") if p.is_file())
            log(f"  {label} [{i + 1}/{repeats}] {run.wall_s:.1f} s, {run.max_rss_mb:.0f} MiB")
    shutil.rmtree(work, ignore_errors=True)
    ours, with_map, floor = (summarize(runs[k]) for k in ("metadata", "with_map", "floor"))
    json_bytes = sum(p.stat().st_size for p in (root / datasets.TRAINVAL_VERSION).glob("*.json"))
    map_bytes = sum(p.stat().st_size for p in (root / "maps" / "expansion").glob("*.json"))
    ratio, map_ratio = ours["wall_s"] / floor["wall_s"], with_map["wall_s"] / floor["wall_s"]
    rows = [
        Row(id="1", benchmark=f"convert trainval-scale metadata, every derived dataset ({json_bytes / 1e9:.2f} GB "
            f"JSON -> {out_bytes['metadata'] / 1e9:.2f} GB Parquet; `--no-map`)",
            ours=f"{seconds(ours['wall_s'])} ({seconds(ours['cpu_s'])} CPU), {megabytes(ours['max_rss_mb'])} peak",
            reference=f"DuckDB floor {seconds(floor['wall_s'])} ({seconds(floor['cpu_s'])} CPU), "
            f"{megabytes(floor['max_rss_mb'])} peak",
            ratio=f"{ratio:.2f}x the floor's time", target=f"≤ {TARGET_RATIO}x, ≤ {TARGET_RSS_MB / 1024:.0f} GB",
            met=ratio <= TARGET_RATIO and ours["max_rss_mb"] <= TARGET_RSS_MB),
        Row(id="1m", benchmark=f"the same with the map expansion ({map_bytes / 1e9:.2f} GB more JSON -> map/ "
            "GeoParquet)", ours=f"{seconds(with_map['wall_s'])} ({seconds(with_map['cpu_s'])} CPU), "
            f"{megabytes(with_map['max_rss_mb'])} peak", reference="the same floor (reads no map JSON)",
            ratio=f"{map_ratio:.2f}x", target="report (the map part's target is row 1m')", met=None),
    ]
    result = {"name": "convert", "command": " ".join(map(str, cmd)), "nuparquet": ours, "with_map": with_map,
              "floor": {"command": " ".join(map(str, floor_cmd)), **floor}, "ratio": ratio, "json_bytes": json_bytes,
              "parquet_bytes": out_bytes, "rows": rows}
    if devkit_repeats:
        import devkit_reference
        from bench_project_scene import first_scene

        devkit = devkit_reference.measure(root, datasets.TRAINVAL_VERSION, first_scene(datasets.trainval_out()),
                                          datasets.trainval_out(), devkit_repeats)
        speedup = devkit["load_wall_s"] / ours["wall_s"]
        rows.append(Row(id="1d", benchmark="the same vs the devkit's bare load", ours=seconds(ours["wall_s"]),
                        reference=f"devkit load {seconds(devkit['load_wall_s'])}, {megabytes(devkit['max_rss_mb'])} peak",
                        ratio=f"speed {times(speedup)}", target="≥ 2x", met=speedup >= 2))
        result["devkit"] = {k: devkit[k] for k in ("command", "repeats", "load_wall_s", "max_rss_mb")}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--devkit-repeats", type=int, default=0)
    args = parser.parse_args()
    from harness import report_alone

    report_alone(run(args.repeats, args.devkit_repeats))


if __name__ == "__main__":
    main()
