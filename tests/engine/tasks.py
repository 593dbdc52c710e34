"""Toy engine tasks (top level, so the process pool and Ray can pickle them by name)."""

from __future__ import annotations

from pathlib import Path

from nuparquet.engine import WorkUnit


def square_into_part(unit: WorkUnit, part: Path) -> int:
    """Writes `unit.args ** 2` into part/value.txt and returns it; raises ValueError for a negative `args`."""
    if unit.args < 0:
        raise ValueError(f"negative input {unit.args}")
    (part / "value.txt").write_text(str(unit.args ** 2))
    return unit.args ** 2
