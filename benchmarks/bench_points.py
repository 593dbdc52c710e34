"""Points row: lidar points conversion throughput against its floor, with 1 and 2 jobs, and reading one scene's
keyframe clouds through `ds.points` against `np.fromfile`, in one run.

    .venv/bin/python benchmarks/bench_points.py [--scenes 16] [--repeats 3]

Data: the real two-scene extract (`../shared/data/nuscenes-extract`: 81 LIDAR_TOP keyframes, ~34.7k points
each, 54 MB). For the conversion row its scenes are repeated to `--scenes` scene tasks (task i converts the
lidar keyframes of real scene i % 2 under the name scene-i): real clouds, a volume where start-up does not
dominate. The files stay in the page cache for every contender alike.

Measured, each in a fresh process (wall time, peak RSS; the figure used is timed in-process around the work):
- ours: `nuparquet.conversion.builders.points.run_scene_tasks(tasks, directory, options)` — what `convert --sensors lidar
  --jobs N` runs after the tables: per scene, read every .pcd.bin, check it, build the Arrow columns
  (dictionary-encoded token/scene/channel, timestamp, point_index, x/y/z/intensity, ring, null labels) and
  write one zstd Parquet part, whole frames per row group;
- floor: the same files, one process: `np.fromfile` + a pyarrow table of the same five arrays (x, y, z,
  intensity, ring as float32) + `pq.write_table(zstd, no dictionary: the fastest honest write)`, one file per
  scene;
- read: `ds.points(the 40 keyframe tokens of scene-0523)` on the converted extract (first call, footers
  included; then warm) against `np.fromfile` of the same 40 files + concatenate.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import REPO, log, python_child, repeat, summarize  # noqa: E402

EXTRACT = REPO.parent / "shared" / "data" / "nuscenes-extract"
VERSION = "v1.0-mini-extract"
CACHE = REPO / ".bench-cache" / "points"
READ_SCENE = "scene-0523"


def prepare() -> Path:
    """The extract converted with its lidar points (read row) — also gives the frame lists of the tasks."""
    out = CACHE / "extract-out"
    if not (out / "manifest.json").is_file():
        from nuparquet.conversion import convert

        shutil.rmtree(out, ignore_errors=True)
        log(f"converting {EXTRACT} with --sensors lidar into {out}")
        convert(EXTRACT, VERSION, out, sensors=("lidar",), workers=1)
    return out


def _tasks(out: str, scenes: int, directory: str):
    import polars as pl

    from nuparquet.conversion.scene_points import SceneTask

    frames = (pl.scan_parquet(f"{out}/frames/*.parquet")
              .filter((pl.col("modality").cast(pl.String) == "lidar") & pl.col("is_key_frame"))
              .select("token", "scene_name", pl.col("channel").cast(pl.String), "timestamp", "is_key_frame", "filename")
              .with_columns(lidarseg=pl.lit(None, pl.String), panoptic=pl.lit(None, pl.String))
              .sort("scene_name", "channel", "timestamp").collect())
    real = [rows.drop("scene_name").to_dict(as_series=False)
            for _, rows in frames.partition_by("scene_name", as_dict=True, maintain_order=True).items()]
    return [SceneTask(str(EXTRACT), f"{directory}/part-{i:05d}.parquet", i, f"scene-{i:04d}", "lidar", real[i % len(real)])
            for i in range(scenes)]


def child_convert(out: str, scenes: str, jobs: str, directory: str) -> None:
    from nuparquet.conversion.builders.points import run_scene_tasks
    from nuparquet.engine import EngineOptions

    tasks = _tasks(out, int(scenes), directory)
    Path(directory).mkdir(parents=True, exist_ok=True)
    engine = EngineOptions(workers=int(jobs))  # run_scene_tasks: serial for 1 worker, else processes
    start, cpu = time.perf_counter(), time.process_time()
    summaries = run_scene_tasks(tasks, Path(directory), engine, lambda scene: None)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu  # cpu: this process only (not workers)
    input_bytes = sum((EXTRACT / f).stat().st_size for t in tasks for f in t.frames["filename"])
    print(json.dumps({"in_process_s": elapsed, "in_process_cpu_s": cpu, "points": sum(s.rows for s in summaries),
                      "input_bytes": input_bytes,
                      "output_bytes": sum(s.bytes for s in summaries)}))


def child_floor(out: str, scenes: str, directory: str) -> None:
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    tasks = _tasks(out, int(scenes), directory)
    Path(directory).mkdir(parents=True, exist_ok=True)
    start, cpu = time.perf_counter(), time.process_time()
    points = 0
    for task in tasks:
        clouds = [np.fromfile(EXTRACT / f, dtype=np.float32).reshape(-1, 5) for f in task.frames["filename"]]
        cloud = np.concatenate(clouds)
        table = pa.table({name: cloud[:, j] for j, name in enumerate(("x", "y", "z", "intensity", "ring"))})
        pq.write_table(table, f"{directory}/part-{task.part:05d}.parquet", compression="zstd", use_dictionary=False)
        points += len(cloud)
    print(json.dumps({"in_process_s": time.perf_counter() - start, "in_process_cpu_s": time.process_time() - cpu,
                      "points": points}))


def child_read(out: str) -> None:
    import numpy as np
    import polars as pl

    import nuparquet

    frames = (pl.scan_parquet(f"{out}/frames/*.parquet")
              .filter((pl.col("scene_name") == READ_SCENE) & (pl.col("modality").cast(pl.String) == "lidar")
                      & pl.col("is_key_frame")).sort("timestamp").select("token", "filename").collect())
    tokens, files = frames["token"].to_list(), [EXTRACT / f for f in frames["filename"]]
    start = time.perf_counter()
    ds = nuparquet.open(out)
    ours = ds.points(tokens)
    first_s = time.perf_counter() - start
    warm = []
    for _ in range(5):
        start = time.perf_counter()
        ds.points(tokens)
        warm.append(time.perf_counter() - start)
    floor = []
    for _ in range(5):
        start = time.perf_counter()
        expected = np.concatenate([np.fromfile(f, dtype=np.float32).reshape(-1, 5) for f in files])
        floor.append(time.perf_counter() - start)
    assert np.array_equal(ours, expected)
    print(json.dumps({"frames": len(tokens), "points": len(ours), "first_s": first_s,
                      "warm_s": float(np.median(warm)), "floor_s": float(np.median(floor))}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        {"convert": child_convert, "floor": child_floor, "read": child_read}[args.child[0]](*args.child[1:])
        return
    out = prepare()
    scratch = CACHE / "scratch"

    def fresh(name: str) -> str:
        shutil.rmtree(scratch, ignore_errors=True)
        return str(scratch / name)

    results = {}
    for label, cmd in (("floor", ["floor"]), ("ours_1_job", ["convert", "1"]), ("ours_2_jobs", ["convert", "2"])):
        runs = []
        for _ in range(args.repeats):  # a fresh output folder per run
            extra = [fresh(label)]
            runs += repeat(python_child(__file__, "--child", cmd[0], str(out), str(args.scenes), *cmd[1:], *extra), 1,
                           label=label)
        results[label] = summarize(runs, in_process_s="in_process_s", in_process_cpu_s="in_process_cpu_s", points="points",
                                   input_bytes="input_bytes", output_bytes="output_bytes")
    shutil.rmtree(scratch, ignore_errors=True)
    points = results["floor"]["points"]
    input_mb = results["ours_1_job"]["input_bytes"] / 2**20
    for label in results:
        seconds = results[label]["in_process_s"]
        results[label]["mpoints_per_s"] = points / seconds / 1e6
        results[label]["input_mb_per_s"] = input_mb / seconds
    results["ratio_1_job_vs_floor"] = results["floor"]["in_process_s"] / results["ours_1_job"]["in_process_s"]
    # On a shared, overloaded box wall time mostly measures the scheduler; CPU time of the one process says more.
    results["cpu_ratio_1_job_vs_floor"] = results["floor"]["in_process_cpu_s"] / results["ours_1_job"]["in_process_cpu_s"]
    results["speedup_2_jobs"] = results["ours_1_job"]["in_process_s"] / results["ours_2_jobs"]["in_process_s"]
    read_runs = repeat(python_child(__file__, "--child", "read", str(out)), args.repeats, label="ds.points 40 clouds")
    read = summarize(read_runs, first_s="first_s", warm_s="warm_s", floor_s="floor_s", points="points")
    read["ratio_first_vs_floor"] = read["floor_s"] / read["first_s"]
    read["ratio_warm_vs_floor"] = read["floor_s"] / read["warm_s"]
    results["read"] = read
    results["load_average"] = __import__("os").getloadavg()
    lidar_bytes = sum(p.stat().st_size for p in (EXTRACT / "samples" / "LIDAR_TOP").glob("*.pcd.bin"))
    parquet_bytes = sum(p.stat().st_size for p in (out / "lidar_points").glob("*.parquet"))
    results["extract_lidar_points_bytes"] = parquet_bytes
    results["extract_pcd_bin_bytes"] = lidar_bytes
    results["scenes"] = args.scenes
    print(json.dumps(results, indent=1, default=str))


if __name__ == "__main__":
    main()
