"""The commit of a job's part files: each finished unit's files moved (renamed, on the same file system) from
its part folder into the output folder, in unit order, so the result does not depend on which engine ran the
units or in what order they finished.

A dataset builder (one Parquet part per scene) and the many-scene render (one video per scene) both end this
way; a builder then writes its manifest, the render its summary.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from nuparquet.atomic import move_into_place
from nuparquet.engine.units import UnitOutcome, forget, part_dir


def numbered(index: int, unit: str, filename: str) -> str:
    """The default name of a committed part: `<unit number, 5 digits>-<file name>` (`00003-part.parquet`)."""
    return f"{index:05d}-{filename}"


def move_parts(outcomes: Sequence[UnitOutcome], parts_dir: Path, dest_dir: Path, *,
               name: Callable[[int, str, str], str] = numbered,
               skip: Callable[[UnitOutcome], bool] = lambda outcome: False) -> list[Path]:
    """Move the part files of every successful unit (not `skip(outcome)`) into `dest_dir`, in unit order, named
    `name(unit number, unit name, file name)`; the units' part folders and markers are removed. Returns the
    committed paths in that order. `parts_dir` and `dest_dir` must be on one file system (a rename)."""
    dest_dir.mkdir(parents=True, exist_ok=True)
    committed: list[Path] = []
    for index, outcome in enumerate(outcomes):
        if not outcome.ok or skip(outcome):
            continue
        folder = part_dir(parts_dir, outcome.name)
        for source in sorted(folder.iterdir()) if folder.is_dir() else []:
            target = dest_dir / name(index, outcome.name, source.name)
            move_into_place(source, target)
            committed.append(target)
        forget(parts_dir, outcome.name)
    return committed
