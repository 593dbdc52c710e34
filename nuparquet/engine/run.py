"""`run_units`: a top-level function mapped over work units (scenes or scene batches) on one of the engines,
with per-unit part folders, failures reported by unit name, `keep_going` and `resume`.

```python
from nuparquet.engine import EngineOptions, WorkUnit, run_units

def render_one(unit: WorkUnit, part: Path) -> dict:      # top level: it is pickled to the workers
    ...                                                  # writes only into `part`
    return {"frames": 40}                                # JSON-able

outcomes = run_units(render_one, [WorkUnit("scene-0061"), ...], parts_dir=Path("out/.parts"),
                     options=EngineOptions(engine="ray"))
for outcome in outcomes:                                 # in unit order, whatever order they finished in
    ...                                                  # then commit: move each unit's part files into place
```

The same call serves every engine: only `backends.BACKENDS[options.engine]` differs, and each runs the same
`units.execute`. The caller commits (moves part files into the final output, writes its manifest); this module
never touches anything outside `parts_dir`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from nuparquet.engine.backends import BACKENDS, import_ray
from nuparquet.engine.options import EngineOptions
from nuparquet.engine.units import (
    Task, UnitOutcome, UnitsFailed, WorkUnit, forget, part_dir, read_marker, write_marker,
)
from nuparquet.errors import UsageError
from nuparquet.progress import OnProgress, Reporter


def run_units(task: Task, units: Sequence[WorkUnit], *, parts_dir: Path, options: EngineOptions | None = None,
              committed: Mapping[str, Any] | None = None, on_progress: OnProgress | None = None,
              label: str = "scenes", preload: Sequence[str] = ()) -> list[UnitOutcome]:
    """Run `task(unit, part_folder)` for every unit on `options.engine`; return the outcomes in unit order.

    Args:
        task: a top-level function (picklable); it writes only into the part folder it is given.
        units: the work units; their names must be unique.
        parts_dir: where part folders and completion markers live (created; on the final output's file system).
        committed: with `options.resume`, units already committed by an earlier run (name -> the value their
            task returned then): skipped, reported as resumed with that value.
        on_progress: one "scene" unit per finished unit; the task is named `label`.
        preload: modules the process pool's workers may import once in a forkserver (only modules that start no
            thread pool at import: numpy, pyarrow, the task's own light module); empty: spawn.

    Raises:
        UsageError: bad options, duplicate unit names, Ray asked for but not installed.
        UnitsFailed: a unit failed and not `options.keep_going` (raised once the running units stopped; the
            finished units keep their part files and markers for `resume`). With `keep_going` failures are
            returned as outcomes with `error` set (`raise_failures` turns them into the error after commit).
    """
    options = options or EngineOptions()
    check_engine(options)
    names = [unit.name for unit in units]
    if len(set(names)) != len(names):
        raise UsageError(f"work unit names must be unique: {sorted({n for n in names if names.count(n) > 1})}")
    parts_dir.mkdir(parents=True, exist_ok=True)
    committed = committed or {}
    outcomes: list[UnitOutcome | None] = [None] * len(units)
    todo: list[int] = []
    for index, unit in enumerate(units):
        if options.resume and unit.name in committed:
            outcomes[index] = UnitOutcome(unit.name, value=committed[unit.name], resumed=True)
            continue
        previous = read_marker(parts_dir, unit.name) if options.resume else None
        if previous is not None:
            outcomes[index] = UnitOutcome(unit.name, value=previous.value, resumed=True)
            continue
        forget(parts_dir, unit.name)
        todo.append(index)

    stopped = False
    with Reporter(on_progress, label, total=len(units), unit="scene") as reporter:
        if len(todo) < len(units):
            reporter.advance(len(units) - len(todo), step="resumed")
        if todo:
            jobs = [(units[i], part_dir(parts_dir, units[i].name)) for i in todo]
            finished = BACKENDS[options.engine](task, jobs, options, preload)
            try:
                for job_index, outcome in finished:
                    outcomes[todo[job_index]] = outcome
                    if outcome.ok:
                        write_marker(parts_dir, outcome)
                    reporter.advance(step=outcome.name if outcome.ok else f"{outcome.name} failed")
                    if not outcome.ok and not options.keep_going:
                        stopped = True
                        break
            finally:
                finished.close()  # cancels what is left (the process pool waits for running tasks)
    failures = [outcome for outcome in outcomes if outcome is not None and not outcome.ok]
    if failures and stopped:
        raise UnitsFailed(failures, outcomes, finished=False)
    return outcomes  # type: ignore[return-value] - every unit has an outcome unless stopped


def check_engine(options: EngineOptions) -> None:
    """UsageError for --engine ray when Ray is not installed (saying how to install it): call before any work
    starts (the option values themselves are checked when `EngineOptions` is built)."""
    if options.engine == "ray":
        import_ray()


def raise_failures(outcomes: Sequence[UnitOutcome]) -> None:
    """After a `keep_going` job committed what succeeded: UnitsFailed naming every failed unit, if any."""
    failures = [outcome for outcome in outcomes if not outcome.ok]
    if failures:
        raise UnitsFailed(failures, list(outcomes), finished=True)
