"""Row 14: `nuparquet.devkit.can_bus.can_bus_api.NuScenesCanBus` against nuscenes-devkit's `NuScenesCanBus`.

    .venv/bin/python benchmarks/bench_devkit_can_bus.py [--scenes 850] [--repeats 3]

Data: the CAN bus files of row 8 (`bench_can_bus.make_data`: per scene pose 50 Hz, ms_imu, steeranglefeedback and
zoe_veh_info 100 Hz, vehicle_monitor 2 Hz, meta and route; 20 s scenes; no files for the devkit's blacklisted
scenes, as in the real expansion) beside a synthetic set of as many scenes (2 samples each: the tables only name
the scenes), converted once into `.bench-cache/devkit-can-bus-out/` (under NUPARQUET_BENCH_CACHE when set).

Each figure is a fresh child process per repeat (harness.run_child: wall time, peak RSS; the devkit's and ours
alternate, so that a shared box's load weighs on both), the same code on each object:
- 14a construction: `NuScenesCanBus(dataroot)` / `NuScenesCanBus(parquet=OUT)`, timed in the process, and the
  process (interpreter, import, construction).
- 14b every message of every scene: `get_messages(scene, name)` for each scene of the set and each of the eight
  names of `all_messages` (an error — a blacklisted scene, a file that does not exist — counted, as a client's
  `except` would), the whole process. The children print a digest of every answer (message counts, the sums of
  `utime`, of route x and of meta message counts); it must be equal.
- 14c `list_misaligned_routes()`: every scene's route and poses.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit imports pyplot; never open a window

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_can_bus  # noqa: E402
from bench_data import CACHE, PARAMS, convert_command, synth_command  # noqa: E402
from harness import REPO, Row, log, megabytes, python_child, repeat, seconds, summarize  # noqa: E402

VERSION = "v1.0-trainval"
ROOT = CACHE / "devkit-can-bus"
OUT = CACHE / "devkit-can-bus-out"


def make_data(scenes: int) -> tuple[Path, Path]:
    """(dataroot, OUT): the tables of `scenes` short scenes, row 8's CAN bus files linked in, converted."""
    can_files = bench_can_bus.make_data(scenes) / "can_bus"
    params = {"scenes": scenes, "can_bus": str(can_files), "schemas": __import__("bench_data")._schemas_digest()}
    if (OUT / "manifest.json").is_file() and (OUT / PARAMS).is_file() \
            and json.loads((OUT / PARAMS).read_text()) == params:
        return ROOT, OUT
    import shutil
    import subprocess

    shutil.rmtree(ROOT, ignore_errors=True)
    log(f"building {ROOT} ({scenes} scenes of tables) with the CAN bus files of {can_files} ...")
    subprocess.run(synth_command(ROOT, scenes, VERSION, samples_per_scene=2, can_bus=False), check=True, cwd=REPO)
    (ROOT / "can_bus").symlink_to(can_files, target_is_directory=True)
    log(f"converting {ROOT} -> {OUT} ...")
    subprocess.run(convert_command(ROOT, VERSION, OUT), check=True, cwd=REPO)
    (OUT / PARAMS).write_text(json.dumps(params) + "\n")
    return ROOT, OUT


def child(task: str, impl: str, root: str, out: str) -> None:
    import warnings

    warnings.simplefilter("ignore")  # the route-blacklist warnings, the same on both
    start = time.perf_counter()
    if impl == "devkit":
        from nuscenes.can_bus.can_bus_api import NuScenesCanBus
    else:
        from nuparquet.devkit.can_bus.can_bus_api import NuScenesCanBus
    imported = time.perf_counter()
    can = NuScenesCanBus(dataroot=root) if impl == "devkit" else NuScenesCanBus(dataroot=root, parquet=out)
    constructed = time.perf_counter()
    report: dict = {"import_s": imported - start, "construct_s": constructed - imported}
    if task == "messages":
        import polars as pl

        scenes = pl.read_parquet(Path(out) / "tables" / "scene")["name"].to_list()
        digest, errors = [], 0
        for scene in scenes:
            for name in can.all_messages:
                try:
                    answer = can.get_messages(scene, name)
                except Exception:  # noqa: BLE001 - a client's except: blacklisted scenes, absent files
                    errors += 1
                    continue
                if name == "meta":
                    digest.append((len(answer), sum(v["message_count"] for v in answer.values())))
                elif name == "route":
                    digest.append((len(answer), sum(p[0] for p in answer)))
                else:
                    digest.append((len(answer), sum(m["utime"] for m in answer)))
        report |= {"loop_s": time.perf_counter() - constructed, "errors": errors, "answers": len(digest),
                   "messages": sum(d[0] for d in digest if isinstance(d[1], int)),
                   "digest": __import__("hashlib").sha256(repr(digest).encode()).hexdigest()}
    elif task == "misaligned":
        misaligned = can.list_misaligned_routes()
        report |= {"loop_s": time.perf_counter() - constructed, "misaligned": [str(s) for s in misaligned]}
    print(json.dumps(report))
    os._exit(0)  # neither side pays for freeing its objects


def run(repeats: int = 3, scenes: int = 850) -> dict:
    root, out = make_data(scenes)
    log(f"row 14: NuScenesCanBus over {scenes} scenes: construction, every message, misaligned routes")
    measured = {}
    for task in ("construct", "messages", "misaligned"):
        runs = {"devkit": [], "nuparquet": []}
        for _ in range(repeats):  # interleaved: on a shared box the load then weighs on both alike
            for impl in runs:
                runs[impl] += repeat(python_child(__file__, "--child", task, impl, str(root), str(out)), 1,
                                     label=f"{task} {impl}")
        for impl, done in runs.items():
            measured[task, impl] = summarize(done, import_s="import_s", construct_s="construct_s",
                                             loop_s="loop_s") | {"report": done[0].report}
    files = sum(1 for _ in (root / "can_bus").glob("*.json"))
    size_mb = sum(p.stat().st_size for p in (root / "can_bus").glob("*.json")) / 2**20
    rows = []
    c_dev, c_our = measured["construct", "devkit"], measured["construct", "nuparquet"]
    rows.append(Row(id="14a", benchmark=f"`NuScenesCanBus(...)` construction ({scenes} scenes)",
                    ours=f"{seconds(c_our['construct_s'])} in-process, import {seconds(c_our['import_s'])} "
                         f"(process {seconds(c_our['wall_s'])}, {megabytes(c_our['max_rss_mb'])} peak)",
                    reference=f"devkit {seconds(c_dev['construct_s'])} in-process, import "
                              f"{seconds(c_dev['import_s'])} (process {seconds(c_dev['wall_s'])}, "
                              f"{megabytes(c_dev['max_rss_mb'])} peak)",
                    ratio=f"process {c_dev['wall_s'] / c_our['wall_s']:.2f}×; in-process "
                          f"{c_dev['construct_s'] / c_our['construct_s']:.4f}×",
                    target="report", met=None,
                    note="row 14a: the devkit's constructor only checks that the folder exists; ours reads the "
                         "manifest (which lists every converted file). The process figure includes the imports: "
                         "the devkit's module imports matplotlib.pyplot and scipy, ours neither."))
    m_dev, m_our = measured["messages", "devkit"], measured["messages", "nuparquet"]
    same = m_dev["report"]["digest"] == m_our["report"]["digest"]
    rows.append(Row(id="14b", benchmark=f"`get_messages` of every scene x every message name ({scenes} scenes, "
                                        f"{m_dev['report']['answers']:,} answers, {m_dev['report']['messages']:,} "
                                        f"messages; {files:,} files, {size_mb:,.0f} MiB of JSON), fresh process",
                    ours=f"{seconds(m_our['wall_s'])}, {megabytes(m_our['max_rss_mb'])} peak (loop "
                         f"{seconds(m_our['loop_s'])})",
                    reference=f"devkit {seconds(m_dev['wall_s'])}, {megabytes(m_dev['max_rss_mb'])} peak (loop "
                              f"{seconds(m_dev['loop_s'])})",
                    ratio=f"{m_dev['wall_s'] / m_our['wall_s']:.2f}× (loop {m_dev['loop_s'] / m_our['loop_s']:.2f}×)",
                    target="same answers", met=same,
                    note=f"row 14b check: every answer's digest equal: {same}"))
    l_dev, l_our = measured["misaligned", "devkit"], measured["misaligned", "nuparquet"]
    same_list = l_dev["report"]["misaligned"] == l_our["report"]["misaligned"]
    rows.append(Row(id="14c", benchmark=f"`list_misaligned_routes()` ({scenes} scenes), fresh process",
                    ours=f"{seconds(l_our['wall_s'])}, {megabytes(l_our['max_rss_mb'])} peak",
                    reference=f"devkit {seconds(l_dev['wall_s'])}, {megabytes(l_dev['max_rss_mb'])} peak",
                    ratio=f"{l_dev['wall_s'] / l_our['wall_s']:.2f}×", target="same answer", met=same_list))
    return {"name": "devkit_can_bus", "scenes": scenes, "files": files, "json_mb": size_mb,
            "measured": {f"{t}/{i}": v for (t, i), v in measured.items()}, "same_answers": same and same_list,
            "commands": {f"{t}/{i}": " ".join(python_child(__file__, "--child", t, i, str(root), str(out)))
                         for t, i in measured}, "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=850)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(*args.child)
        return
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes))


if __name__ == "__main__":
    main()
