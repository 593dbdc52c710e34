"""Rows 11a-11c: every scene of a 10-scene synthetic set rendered (`render_scenes`, one CAM_FRONT --all-frames
video per scene, ~120 frames each) on one process, a pool of 2 processes and Ray on 2 CPUs: scenes per second, speed-up over one
process, peak RSS per worker, and whether the videos are the same bytes.

    .venv/bin/python benchmarks/bench_scale_out.py [--repeats 1]

Each engine runs in a fresh process (`--child`), which times `render_scenes` (for Ray, the local Ray is
started first and its start-up reported apart: a cluster pays it once) and prints the peak RSS each worker reported after its scenes
(`UnitOutcome.peak_rss_mb`; the driver's own is the process figure of the harness).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

ENGINES = (("1 process", "serial", 1), ("2 processes", "process", 2), ("Ray, 2 CPUs", "ray", 2))


def child(out: str, engine: str, workers: int, out_dir: str) -> None:
    start = time.perf_counter()
    from nuparquet.engine import EngineOptions
    from nuparquet.rendering.video.batch import render_scenes
    from nuparquet.dataset.selection import SceneSelection
    from nuparquet.rendering.video.options import RenderOptions

    import_s = time.perf_counter() - start
    start_s = 0.0
    if engine == "ray":  # started here to report its cost apart (a cluster pays it once, not per job)
        start = time.perf_counter()
        import ray

        ray.init(num_cpus=workers, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
        start_s = time.perf_counter() - start
    start = time.perf_counter()
    result = render_scenes(out, SceneSelection(all_scenes=True), out_dir, RenderOptions(channel="CAM_FRONT", all_frames=True),
                           engine=EngineOptions(engine=engine, workers=workers))
    total_s = time.perf_counter() - start
    videos = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(Path(out_dir).glob("*.mp4"))}
    outcomes = result.outcomes
    print(json.dumps({
        "import_s": import_s, "engine_start_s": start_s, "total_s": total_s, "scenes": len(outcomes),
        "frames": sum(o.value["frames_written"] for o in outcomes),
        "scenes_per_s": len(outcomes) / total_s,
        "worker_peak_rss_mb": max(o.peak_rss_mb for o in outcomes),
        "workers_used": len({o.worker for o in outcomes}),
        "scene_s": sorted(round(o.seconds, 3) for o in outcomes),
        "videos": videos,
    }))


def run(repeats: int = 1) -> dict:
    import bench_data as datasets
    from harness import Row, log, megabytes, python_child, repeat, seconds, summarize

    out = datasets.scale_out_out()
    log(f"rows 11: render all {datasets.SCALE_OUT_SCENES} scenes on 1 process, 2 processes, Ray on 2 CPUs")
    figures, commands, videos = {}, {}, {}
    for label, engine, workers in ENGINES:
        out_dir = Path(tempfile.mkdtemp(prefix="nuparquet-scale-out-"))
        try:
            cmd = python_child(__file__, "--child", out, engine, workers, out_dir)
            runs = repeat(cmd, repeats, label=label)
        finally:
            shutil.rmtree(out_dir, ignore_errors=True)
        figures[label] = summarize(runs, total_s="total_s", engine_start_s="engine_start_s", scenes="scenes",
                                   frames="frames",
                                   scenes_per_s="scenes_per_s", worker_peak_rss_mb="worker_peak_rss_mb",
                                   workers_used="workers_used")
        commands[label] = " ".join(map(str, cmd))
        videos[label] = runs[-1].report["videos"]
    same_bytes = all(v == videos["1 process"] for v in videos.values())
    base = figures["1 process"]["scenes_per_s"]
    rows = []
    for index, (label, engine, _) in enumerate(ENGINES):
        f = figures[label]
        rows.append(Row(
            id=f"11{'abc'[index]}",
            benchmark=f"render all {f['scenes']:.0f} scenes ({f['frames']:.0f} CAM_FRONT frames, --all-frames, "
            f"800x450) of the 10-scene set: {label}",
            ours=f"{f['scenes_per_s']:.2f} scenes/s ({seconds(f['total_s'])}"
            f"{'; process CPU ' + seconds(f['cpu_s']) + ' = ' + format(f['cpu_s'] / f['wall_s'], '.2f') + ' cores busy' if engine == 'serial' else ''}"
            f"{'; + Ray start ' + seconds(f['engine_start_s']) if f['engine_start_s'] else ''}; worker peak "
            f"{megabytes(f['worker_peak_rss_mb'])}, process {megabytes(f['max_rss_mb'])})",
            reference=f"1 process: {base:.2f} scenes/s",
            ratio=f"{f['scenes_per_s'] / base:.2f}×",
            target="report; videos the same bytes",
            met=same_bytes,
        ))
    return {"name": "scale_out", "figures": figures, "commands": commands, "same_bytes": same_bytes,
            "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--child", nargs=4, metavar=("OUT", "ENGINE", "WORKERS", "OUT_DIR"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        out, engine, workers, out_dir = args.child
        child(out, engine, int(workers), out_dir)
        return
    from harness import report_alone

    report_alone(run(args.repeats))


if __name__ == "__main__":
    main()
