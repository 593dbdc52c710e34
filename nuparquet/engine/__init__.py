"""The scale-out engine: one function mapped over work units (scenes or scene batches) on a local process pool,
on Ray (a local Ray or a cluster), or serially, through the same code path (`run_units`).

A job (rendering every scene, converting every scene's points) gives a top-level task function; each unit's
task writes its own part files into a folder the engine gives it; the job commits them (moving them into the
final output, writing its manifest) once the units are done. Outcomes come back in unit order, so a commit is
deterministic whichever engine ran the units and in whatever order they finished.
"""

import importlib

# name -> module: loaded on first use, so `nuparquet.engine.options` (the CLI's flags) does not load the process
# pool, Ray glue and multiprocessing with it (~20 ms of every `nuparquet` command).
_WHERE = {"move_parts": "commit", "ENGINES": "options", "EngineOptions": "options", "check_engine": "run",
          "raise_failures": "run", "run_units": "run", "UnitOutcome": "units", "UnitsFailed": "units",
          "WorkUnit": "units", "unit_file_name": "units"}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module 'nuparquet.engine' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"nuparquet.engine.{_WHERE[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_WHERE))
