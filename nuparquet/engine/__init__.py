"""The scale-out engine: one function mapped over work units (scenes or scene batches) on a local process pool,
on Ray (a local Ray or a cluster), or serially, through the same code path (`run_units`).

A job (rendering every scene, converting every scene's points) gives a top-level task function; each unit's
task writes its own part files into a folder the engine gives it; the job commits them (moving them into the
final output, writing its manifest) once the units are done. Outcomes come back in unit order, so a commit is
deterministic whichever engine ran the units and in whatever order they finished.
"""

from nuparquet.engine.commit import move_parts
from nuparquet.engine.options import ENGINES, EngineOptions
from nuparquet.engine.run import check_engine, raise_failures, run_units
from nuparquet.engine.units import UnitOutcome, UnitsFailed, WorkUnit, unit_file_name

__all__ = ["ENGINES", "EngineOptions", "UnitOutcome", "UnitsFailed", "WorkUnit", "check_engine", "move_parts", "unit_file_name", "raise_failures",
           "run_units"]
