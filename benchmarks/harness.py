"""Measuring benchmarks: one fresh child process per measurement, its wall time and peak RSS, medians, ratios.

Every figure in BENCHMARKS.md comes from `run_child`: the command runs in a new process, started by the small
launcher `launch.py` and reaped there with `os.wait4`, which returns that process's own resource usage (peak
RSS `ru_maxrss`, user and system CPU). `getrusage(RUSAGE_CHILDREN)` would keep the running maximum over all
children instead, and a child started straight from this (big) process would inherit its RSS high-water mark.
A child may print one JSON object as the last line of its stdout: in-process timings it took itself.

The machines are shared and noisy, so each benchmark measures its reference in the same run and reports the
ratio of medians.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BENCH_DIR = REPO / "benchmarks"
RESULTS_DIR = BENCH_DIR / "results"
PYTHON = sys.executable
LAUNCHER = BENCH_DIR / "launch.py"
# The console script users run (installed next to the interpreter by `pip install -e .`).
_SCRIPT = Path(PYTHON).with_name("nuparquet")
NUPARQUET = [str(_SCRIPT)] if _SCRIPT.is_file() else [PYTHON, "-m", "nuparquet.cli.main"]


@dataclass
class Run:
    """One child process: wall time (s), peak RSS (MiB), CPU seconds, and the JSON it reported (if any)."""

    wall_s: float
    max_rss_mb: float
    cpu_s: float
    report: dict = field(default_factory=dict)
    stdout: str = field(default="", repr=False)


class ChildFailed(RuntimeError):
    pass


def run_child(cmd: list[str], *, cwd: Path | None = None, env: dict | None = None, timeout_s: float = 3600) -> Run:
    """Run `cmd` in a fresh process; return its wall time, peak RSS and CPU time, and the JSON of its last line.

    The command is started by `launch.py` (a small stdlib-only interpreter) rather than by this process: a
    child started from here would inherit this process's RSS high-water mark (see launch.py). Wall time is
    measured by the launcher from spawn to reaping, so the launcher's own start-up is not included.
    Raises ChildFailed (with the tail of stderr) if it exits non-zero or runs past `timeout_s`.
    """
    with tempfile.TemporaryDirectory(prefix="nuparquet-bench-") as tmp:
        report_path = Path(tmp) / "rusage.json"
        with open(Path(tmp) / "stdout", "w+b") as out, open(Path(tmp) / "stderr", "w+b") as err:
            proc = subprocess.Popen([PYTHON, "-S", str(LAUNCHER), str(report_path), *map(str, cmd)],
                                    cwd=cwd or REPO, env=env, stdout=out, stderr=err, stdin=subprocess.DEVNULL,
                                    start_new_session=True)
            try:
                returncode = proc.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, 9)
                proc.wait()
                raise ChildFailed(f"{' '.join(map(str, cmd))} ran longer than {timeout_s:.0f} s") from None
            out.seek(0)
            err.seek(0)
            stdout, stderr = out.read().decode(errors="replace"), err.read().decode(errors="replace")
        usage = json.loads(report_path.read_text()) if report_path.is_file() else None
    if returncode != 0 or usage is None:
        raise ChildFailed(f"{' '.join(map(str, cmd))} exited {returncode}:\n{stderr[-3000:]}")
    report = {}
    lines = stdout.strip().splitlines()
    if lines and lines[-1].startswith("{"):
        try:
            report = json.loads(lines[-1])
        except json.JSONDecodeError:
            report = {}
    return Run(wall_s=usage["wall_s"], max_rss_mb=usage["max_rss_kb"] / 1024,
               cpu_s=usage["user_s"] + usage["system_s"], report=report, stdout=stdout)


def python_child(script: Path | str, *args: str) -> list[str]:
    """The command running one of the benchmark scripts with this interpreter."""
    return [PYTHON, str(script), *map(str, args)]


def repeat(cmd: list[str], times: int, *, label: str = "", **kwargs) -> list[Run]:
    """`times` fresh runs of `cmd`, one after the other (never in parallel: they would share two cores)."""
    runs = []
    for i in range(times):
        run = run_child(cmd, **kwargs)
        runs.append(run)
        log(f"  {label or cmd[-1]} [{i + 1}/{times}] {run.wall_s:.2f} s, {run.max_rss_mb:.0f} MiB")
    return runs


def median(values) -> float:
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else float("nan")


def summarize(runs: list[Run], **report_keys: str) -> dict:
    """Medians of wall time, peak RSS and CPU time over `runs`, plus the median of each reported key given as
    `name=key` (a key of the child's JSON report), and the raw walls."""
    summary = {
        "repeats": len(runs),
        "wall_s": median(r.wall_s for r in runs),
        "max_rss_mb": median(r.max_rss_mb for r in runs),
        "cpu_s": median(r.cpu_s for r in runs),
        "walls_s": [round(r.wall_s, 4) for r in runs],
    }
    for name, key in report_keys.items():
        summary[name] = median(r.report.get(key) for r in runs)
    return summary


def ratio(reference: float, ours: float) -> float:
    """How many times faster (or leaner) ours is: reference / ours."""
    return reference / ours if ours else float("inf")


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def machine() -> dict:
    """Cores, RAM, CPU model, OS and the versions that matter for the figures."""
    cpu_model = "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu_model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    ram_gb = float("nan")
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                ram_gb = int(line.split()[1]) / 1024 / 1024
    except OSError:
        pass
    versions = {}
    for module in ("polars", "pyarrow", "duckdb", "numpy", "cv2", "av", "nuparquet"):
        try:
            versions[module] = __import__(module).__version__
        except Exception:  # noqa: BLE001 - a missing module is just not reported
            pass
    try:
        from importlib.metadata import version

        versions["nuscenes-devkit"] = version("nuscenes-devkit")
    except Exception:  # noqa: BLE001
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True,
                                check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "?"
    return {
        "cores": os.cpu_count(),
        "ram_gb": round(ram_gb, 1),
        "cpu_model": cpu_model,
        "os": platform.platform(),
        "python": platform.python_version(),
        "versions": versions,
        "commit": commit,
    }


def load_average() -> list[float]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


def write_results(results: dict, name: str | None = None) -> Path:
    """Write `results` to benchmarks/results/<UTC date and time>[-name].json and return the path."""
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H%M%SZ")
    path = RESULTS_DIR / (f"{stamp}-{name}.json" if name else f"{stamp}.json")
    path.write_text(json.dumps(results, indent=1, default=_jsonable) + "\n")
    return path


def _jsonable(value):
    if hasattr(value, "__dataclass_fields__"):
        return asdict(value)
    if hasattr(value, "item"):
        return value.item()
    return str(value)


# --- the table ---------------------------------------------------------------------------------------------------

@dataclass
class Row:
    """One line of the results table: what was measured, our figure, the reference's, the ratio and the target."""

    benchmark: str
    ours: str
    reference: str
    ratio: str
    target: str
    met: bool | None  # None: nothing to meet (report only)
    note: str = ""
    id: str = ""  # the row's number in the table (1, 2, 3, 4, 5a, 5b, 6a, 6b)


def markdown_table(rows: list[Row]) -> str:
    header = "| # | benchmark | nuparquet | reference (same run) | ratio | target | met |"
    lines = [header, "|---|---|---|---|---|---|---|"]
    for number, row in enumerate(rows, 1):
        met = "—" if row.met is None else ("yes" if row.met else "**no**")
        lines.append(f"| {row.id or number} | {row.benchmark} | {row.ours} | {row.reference} | {row.ratio} | "
                     f"{row.target} | {met} |")
    notes = [f"- {row.note}" for row in rows if row.note]
    return "\n".join(lines + ([""] + notes if notes else []))


def seconds(value: float) -> str:
    if value != value:  # nan
        return "?"
    if value >= 100:
        return f"{value:.0f} s"
    if value >= 10:
        return f"{value:.1f} s"
    if value >= 1:
        return f"{value:.2f} s"
    if value >= 0.01:
        return f"{value:.3f} s"
    return f"{value * 1000:.2f} ms"


def megabytes(value: float) -> str:
    return f"{value / 1024:.2f} GB" if value >= 1024 else f"{value:.0f} MB"


def times(value: float) -> str:
    if value != value:
        return "?"
    return f"{value:,.0f}×" if value >= 100 else f"{value:.1f}×" if value >= 10 else f"{value:.2f}×"


def report_alone(result: dict) -> None:
    """What a benchmark script run on its own prints: its rows as a Markdown table; results JSON written."""
    results = {"machine": machine(), "load_average_end": load_average(), "benchmarks": [result]}
    path = write_results(results, result["name"])
    print(markdown_table(result["rows"]))
    print(f"\n(results: {path.relative_to(REPO)})")
