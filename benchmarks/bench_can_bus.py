"""CAN bus row: convert the CAN bus of an 850-scene synthetic set, then "mean CAN speed per scene", against the
devkit's `NuScenesCanBus.get_messages` loop over the same scenes, in one run.

    .venv/bin/python benchmarks/bench_can_bus.py [--scenes 850] [--repeats 3]

Data: `.bench-cache/can-bus/can_bus/` (under NUPARQUET_BENCH_CACHE when set) — per scene the files `nuparquet.synth.can_bus` writes (pose 50 Hz, ms_imu,
steeranglefeedback and zoe_veh_info 100 Hz, vehicle_monitor 2 Hz, meta, route; 20 s scenes), ~7,100 messages a
scene, generated once from a simple smooth trajectory per scene (the CAN files do not need the tables).

Measured, each in a fresh process (wall time, peak RSS):
- convert: what `nuparquet convert` does for the CAN bus (`sources.can_bus` read + `json_records` typing of every
  file, Parquet written per message type), done once per dataset;
- query: `nuparquet`'s answer from the Parquet: `scan_parquet(can_bus/vehicle_monitor).group_by(scene).mean()`;
- devkit: `NuScenesCanBus(dataroot)` and, per scene, `get_messages(scene, "vehicle_monitor")` and the mean of
  `vehicle_speed` in Python. The two answers are checked equal.
Prints rows 8a-8b and writes benchmarks/results/<UTC time>-can_bus.json; `run_all.py` runs it as `can_bus`.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_data import CACHE as BENCH_CACHE  # noqa: E402
from harness import Row, log, megabytes, python_child, repeat, seconds, summarize  # noqa: E402

CACHE = BENCH_CACHE / "can-bus"


def make_data(scenes: int) -> Path:
    from nuparquet.synth.can_bus import write_scene_can_bus

    marker = CACHE / f".scenes-{scenes}"
    if marker.exists():
        return CACHE
    shutil.rmtree(CACHE, ignore_errors=True)
    CACHE.mkdir(parents=True)
    log(f"writing the CAN bus files of {scenes} synthetic scenes into {CACHE}")
    from nuparquet.can_bus.blacklists import CAN_BLACKLIST

    for i in range(scenes):
        if i + 1 in CAN_BLACKLIST:  # like the real expansion: no files for the scenes the devkit refuses
            continue
        rng = np.random.default_rng([7, i])
        start = 1_530_000_000_000_000 + i * 100_000_000
        samples = start + np.arange(40, dtype=np.int64) * 500_000
        frames = np.arange(start, samples[-1] + 1, 50_000, dtype=np.int64)
        t = (frames - start) / 1e6
        speed = 5 + 3 * np.sin(t / 4 + rng.uniform(0, 6))
        yaw = 0.3 * np.sin(t / 7 + rng.uniform(0, 6))
        xy = np.cumsum(np.c_[np.cos(yaw), np.sin(yaw)] * (speed * 0.05)[:, None], axis=0)
        write_scene_can_bus(CACHE, f"scene-{i + 1:04d}", rng, samples, frames, np.c_[xy, np.zeros(len(xy))], yaw)
    marker.touch()
    return CACHE


def child_convert(root: str, out: str) -> None:
    start = time.perf_counter()
    from nuparquet.conversion.write import write_parquet
    from nuparquet.sources import can_bus

    root_path = Path(root)
    scenes = {p.name.split("_")[0] for p in (root_path / "can_bus").glob("scene-*_*.json")}
    found, _ = can_bus.discover(root_path, scenes)
    rows = 0
    for message, files in found.items():
        reader = {can_bus.META: can_bus.read_meta, can_bus.ROUTE: can_bus.read_route}.get(message, can_bus.read_messages)
        read, problems = reader(root_path, files)
        assert not problems, problems[:3]
        write_parquet(read.table, Path(out) / "can_bus" / message, group_by="scene_name")
        rows += read.table.num_rows
    print(json.dumps({"in_process_s": time.perf_counter() - start, "rows": rows}))


def child_query(out: str) -> None:
    start = time.perf_counter()
    import polars as pl

    means = (pl.scan_parquet(f"{out}/can_bus/vehicle_monitor/*.parquet").group_by("scene_name")
             .agg(pl.col("vehicle_speed").mean()).sort("scene_name").collect())
    print(json.dumps({"in_process_s": time.perf_counter() - start,
                      "means": dict(zip(means["scene_name"].to_list(), means["vehicle_speed"].to_list()))}))


def child_devkit(root: str) -> None:
    start = time.perf_counter()
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus

    can = NuScenesCanBus(dataroot=root)
    scenes = sorted({p.name.split("_")[0] for p in (Path(root) / "can_bus").glob("scene-*_vehicle_monitor.json")})
    means = {}
    for scene in scenes:
        speeds = [m["vehicle_speed"] for m in can.get_messages(scene, "vehicle_monitor")]
        means[scene] = sum(speeds) / len(speeds)
    print(json.dumps({"in_process_s": time.perf_counter() - start, "means": means}))


def run(repeats: int = 3, scenes: int = 850) -> dict:
    """Row 8: the CAN bus converted, then mean speed per scene from the Parquet vs the devkit's loop."""
    root = make_data(scenes)
    out = BENCH_CACHE / "can-bus-out"
    log(f"row 8: CAN bus of {scenes} scenes: convert, query vs the devkit's get_messages loop")
    shutil.rmtree(out, ignore_errors=True)
    convert_cmd = python_child(__file__, "--child", "convert", str(root), str(out))
    convert = summarize(repeat(convert_cmd, repeats, label="nuparquet convert CAN bus"), in_process_s="in_process_s")
    query_cmd = python_child(__file__, "--child", "query", str(out))
    devkit_cmd = python_child(__file__, "--child", "devkit", str(root))
    query_runs = repeat(query_cmd, repeats, label="nuparquet query")
    devkit_runs = repeat(devkit_cmd, repeats, label="devkit loop")
    query, devkit = summarize(query_runs, in_process_s="in_process_s"), summarize(devkit_runs, in_process_s="in_process_s")
    ours_means, their_means = query_runs[0].report["means"], devkit_runs[0].report["means"]
    same = ours_means.keys() == their_means.keys() and all(
        abs(ours_means[k] - their_means[k]) <= 1e-9 * abs(their_means[k]) for k in their_means)
    files = sum(1 for _ in (root / "can_bus").glob("*.json"))
    size_mb = sum(p.stat().st_size for p in (root / "can_bus").glob("*.json")) / 2**20
    speedup = devkit["wall_s"] / query["wall_s"]
    rows = [
        Row(id="8a", benchmark=f"convert the CAN bus of {scenes} synthetic scenes ({files:,} files, {size_mb:,.0f} MiB "
            "of JSON -> can_bus/<message> Parquet)",
            ours=f"{seconds(convert['wall_s'])}, {megabytes(convert['max_rss_mb'])} peak", reference="—", ratio="—",
            target="report", met=None),
        Row(id="8b", benchmark="mean CAN vehicle_speed per scene, fresh process",
            ours=f"{seconds(query['wall_s'])}, {megabytes(query['max_rss_mb'])} peak",
            reference=f"devkit NuScenesCanBus + get_messages per scene: {seconds(devkit['wall_s'])}, "
            f"{megabytes(devkit['max_rss_mb'])} peak",
            ratio=f"{speedup:.1f}x", target="same answers", met=same,
            note=f"row 8 check: mean speeds equal to the devkit's (1e-9): {same}"),
    ]
    return {"name": "can_bus", "scenes": scenes, "files": files, "json_mb": size_mb, "convert": convert,
            "query": query, "devkit": devkit, "same_answer": same, "query_speedup": speedup,
            "convert_vs_devkit": devkit["wall_s"] / convert["wall_s"],
            "commands": {"convert": " ".join(map(str, convert_cmd)), "query": " ".join(map(str, query_cmd)),
                         "devkit": " ".join(map(str, devkit_cmd))}, "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=850)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        {"convert": child_convert, "query": child_query, "devkit": child_devkit}[args.child[0]](*args.child[1:])
        return
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes))


if __name__ == "__main__":
    main()
