"""Every benchmark of BENCHMARKS.md, one after the other (`make bench`):

    .venv/bin/python benchmarks/run_all.py [--repeats 3] [--devkit-repeats 3] [--only convert,render ...]

Builds the cached datasets first if needed (`bench_data.py`; NUPARQUET_BENCH_CACHE=DIR keeps them in DIR), then
runs every row: 1-6, 7 (index), 8 (CAN bus), 9 (map), 10 (points), 11 (scale-out), the map conversion's floor
(1m'), 12 (the devkit's clients on nuparquet.devkit.NuScenes), 13 (evaluation) and the start-up (s1, s2). The
devkit reference (`devkit_reference.py`, ~40 s and ~8 GB per fresh process at trainval scale) is measured once
per repeat and shared by rows 1-3. Prints the machine and one Markdown table, and writes
benchmarks/results/<UTC time>.json (every figure and command) and .md (what BENCHMARKS.md records).
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_analytics  # noqa: E402
import bench_can_bus  # noqa: E402
import bench_convert  # noqa: E402
import bench_data  # noqa: E402
import bench_devkit_compat  # noqa: E402
import bench_eval  # noqa: E402
import bench_first_query  # noqa: E402
import bench_index  # noqa: E402
import bench_map  # noqa: E402
import bench_points  # noqa: E402
import bench_project_all  # noqa: E402
import bench_project_scene  # noqa: E402
import bench_render  # noqa: E402
import map_floor  # noqa: E402
import bench_scale_out  # noqa: E402
import bench_startup  # noqa: E402
import bench_training_loader  # noqa: E402
from harness import REPO, load_average, log, machine, markdown_table, write_results  # noqa: E402

BENCHMARKS = {
    "convert": lambda a: bench_convert.run(a.repeats, a.devkit_repeats),
    "map_convert": lambda a: map_floor.run(a.repeats),
    "first_query": lambda a: bench_first_query.run(max(a.repeats, 5), a.devkit_repeats),
    "project_scene": lambda a: bench_project_scene.run(a.repeats, a.devkit_repeats),
    "project_all": lambda a: bench_project_all.run(a.repeats),
    "render": lambda a: bench_render.run(a.repeats),
    "analytics": lambda a: bench_analytics.run(a.repeats),
    "index": lambda a: bench_index.run(a.repeats),
    "can_bus": lambda a: bench_can_bus.run(a.repeats),
    "map": lambda a: bench_map.run(a.repeats, devkit_repeats=a.devkit_repeats),
    "points": lambda a: bench_points.run(a.repeats),
    "scale_out": lambda a: bench_scale_out.run(1),
    # the devkit's object is built once per measurement (~1 min and ~8 GB each at trainval scale)
    # the infos loop on the first 2,000 samples: over all 34,000 the devkit alone takes ~50 min
    "devkit_compat": lambda a: bench_devkit_compat.run(850, a.repeats, min(a.devkit_repeats, 1), samples=2000),
    "eval": lambda a: bench_eval.run(a.repeats, min(a.devkit_repeats, 1)),
    "startup": lambda a: bench_startup.run(max(a.repeats, 20)),
    "training_loader": lambda a: bench_training_loader.run(repeats=a.repeats),
}


def machine_markdown(info: dict) -> str:
    versions = ", ".join(f"{k} {v}" for k, v in info["versions"].items())
    return (f"- machine: {info['cores']} cores, {info['ram_gb']} GB RAM, {info['cpu_model']}; {info['os']}\n"
            f"- Python {info['python']}; {versions}\n- nuparquet commit {info['commit']}")


def commands_markdown(results: list[dict]) -> str:
    lines = []
    for result in results:
        commands = {}
        if "command" in result:
            commands["nuparquet"] = result["command"]
        if isinstance(result.get("devkit"), dict) and "command" in result["devkit"]:
            commands["devkit reference"] = result["devkit"]["command"]
        commands.update(result.get("commands", {}))
        for mode, figures in result.get("modes", {}).items():
            for name, command in figures["commands"].items():
                commands[f"{mode}, {name}"] = command
        for name, command in commands.items():
            lines.append(f"- {result['name']} ({name}): `{command.replace(str(REPO) + '/', '')}`")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3, help="fresh processes per measurement (median; default 3)")
    parser.add_argument("--devkit-repeats", type=int, default=3,
                        help="devkit reference processes (each ~40 s, ~8 GB at trainval scale; default 3)")
    parser.add_argument("--only", help=f"comma-separated subset of: {', '.join(BENCHMARKS)}")
    args = parser.parse_args()
    wanted = args.only.split(",") if args.only else list(BENCHMARKS)
    unknown = [name for name in wanted if name not in BENCHMARKS]
    if unknown:
        parser.error(f"unknown benchmark(s) {', '.join(unknown)}; choose from {', '.join(BENCHMARKS)}")

    started = dt.datetime.now(dt.timezone.utc)
    start = time.perf_counter()
    log("datasets:")
    bench_data.trainval_out()
    if "render" in wanted:
        bench_data.render_out()
    info = machine()
    load_start = load_average()
    results, failed = [], []
    for name in wanted:
        try:
            results.append(BENCHMARKS[name](args))
        except Exception as exc:  # one broken benchmark must not lose the others' figures
            log(f"{name} FAILED: {exc}")
            failed.append(f"{name}: {str(exc).splitlines()[0]}")
    rows = [row for result in results for row in result["rows"]]
    table = markdown_table(rows)
    elapsed = time.perf_counter() - start
    header = (f"### Run of {started.strftime('%Y-%m-%d %H:%M UTC')} (`benchmarks/run_all.py --repeats {args.repeats} "
              f"--devkit-repeats {args.devkit_repeats}`, {elapsed / 60:.1f} min)\n\n{machine_markdown(info)}\n"
              f"- load average at start {load_start}, at end {load_average()} (the machine is shared)\n")
    report = (f"{header}\n{table}\n\nCommands (each a fresh process; medians of the repeats):\n\n"
              f"{commands_markdown(results)}\n" + "".join(f"\n**Failed**: {line}\n" for line in failed))
    path = write_results({"started_utc": started.isoformat(), "elapsed_s": elapsed, "machine": info,
                          "load_average": {"start": load_start, "end": load_average()},
                          "repeats": args.repeats, "devkit_repeats": args.devkit_repeats, "benchmarks": results,
                          "failed": failed})
    path.with_suffix(".md").write_text(report)
    print(report)
    print(f"(results: {path.relative_to(REPO)} and {path.with_suffix('.md').relative_to(REPO)})")


if __name__ == "__main__":
    main()
