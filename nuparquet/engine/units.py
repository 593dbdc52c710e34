"""Work units and what became of them: the part folder each unit writes into, its outcome, and the marker that
says a unit finished (so `--resume` can skip it).

Layout under a job's `parts_dir` (a hidden folder on the same file system as the final output):

    parts_dir/<unit>/            the unit's part files, written by its task only (cleared before it starts)
    parts_dir/<unit>.done.json   written by the driver once the task returned: the unit is complete
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import time
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable
from urllib.parse import quote

from nuparquet.errors import InputError, NuparquetError
from nuparquet.atomic import write_text_atomic


@dataclass(frozen=True)
class WorkUnit:
    """One unit of a job: `name` (a scene name; it names the unit in reports and its part folder) and `args`,
    anything picklable the task needs beyond the name (a scene batch, options)."""

    name: str
    args: Any = None


@dataclass(frozen=True)
class UnitOutcome:
    """What became of a unit. `value`: what its task returned (JSON-able); `error`: why it failed (None if it
    did not); `resumed`: finished by an earlier run and skipped; `seconds`, `peak_rss_mb`, `worker`: the task's
    wall time, the peak resident memory of the process that ran it so far, and that process's id."""

    name: str
    value: Any = None
    error: str | None = None
    resumed: bool = False
    seconds: float = 0.0
    peak_rss_mb: float = 0.0
    worker: int = 0

    @property
    def ok(self) -> bool:
        return self.error is None


# A task: a top-level (picklable) function of the unit and its part folder, returning a JSON-able value.
Task = Callable[[WorkUnit, Path], Any]


class UnitsFailed(InputError):
    """Units of a job failed; the message names each with its error (exit code 1)."""

    def __init__(self, failures: list[UnitOutcome], outcomes: list[UnitOutcome | None], *, finished: bool):
        self.failures = failures
        self.outcomes = outcomes
        lines = "\n".join(f"  {failure.name}: {failure.error}" for failure in failures)
        tail = ("the other units finished" if finished else
                "the job stopped there and nothing was committed (--keep-going finishes the others)")
        super().__init__(f"{len(failures)} unit(s) failed; {tail}:\n{lines}")


def unit_file_name(unit_name: str) -> str:
    """The file name standing for a unit: its name with anything but letters, digits, '-', '_' and '.' quoted
    (a scene named '../x' cannot leave the parts folder)."""
    name = quote(unit_name, safe="-_.")
    return "%2E" + name[1:] if name.startswith(".") else name or "%00"


def part_dir(parts_dir: Path, unit_name: str) -> Path:
    return parts_dir / unit_file_name(unit_name)


def _marker(parts_dir: Path, unit_name: str) -> Path:
    return parts_dir / f"{unit_file_name(unit_name)}.done.json"


def write_marker(parts_dir: Path, outcome: UnitOutcome) -> None:
    """Record that `outcome`'s unit is complete (written to a temporary name, then renamed)."""
    write_text_atomic(_marker(parts_dir, outcome.name), json.dumps(asdict(outcome)))


def read_marker(parts_dir: Path, unit_name: str) -> UnitOutcome | None:
    """The outcome recorded for a complete unit, or None (never finished, or its marker is damaged)."""
    try:
        fields = json.loads(_marker(parts_dir, unit_name).read_text())
        return UnitOutcome(**fields) if fields.get("name") == unit_name and fields.get("error") is None else None
    except (OSError, ValueError, TypeError):
        return None


def forget(parts_dir: Path, unit_name: str) -> None:
    """Remove a unit's marker and part files (a fresh run, or after they were committed)."""
    _marker(parts_dir, unit_name).unlink(missing_ok=True)
    shutil.rmtree(part_dir(parts_dir, unit_name), ignore_errors=True)


def describe(exc: BaseException) -> str:
    """One line for a failed unit: our own errors as their message; anything else with its type and where it
    was raised (the last frame of the traceback)."""
    if isinstance(exc, NuparquetError):
        return str(exc)
    frames = traceback.extract_tb(exc.__traceback__)
    where = f" (at {Path(frames[-1].filename).name}:{frames[-1].lineno})" if frames else ""
    return f"{type(exc).__name__}: {exc}{where}"


def execute(task: Task, unit: WorkUnit, part: str) -> UnitOutcome:
    """Run `task` on `unit` with a fresh part folder; on any error the folder is removed and the error returned
    (never raised: an exception would have to be picklable to cross a process or a Ray task)."""
    folder = Path(part)
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    start = time.perf_counter()
    try:
        value = task(unit, folder)
        error = None
    except Exception as exc:  # noqa: BLE001 - reported by name, the job decides whether to go on
        value, error = None, describe(exc)
        shutil.rmtree(folder, ignore_errors=True)
    peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    return UnitOutcome(unit.name, value=value, error=error, seconds=time.perf_counter() - start,
                       peak_rss_mb=round(peak_rss_mb, 1), worker=os.getpid())
