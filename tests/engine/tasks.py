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


STATE: dict = {}  # set by a test in its own process: a worker that sees it was forked from that process


def parent_state_seen(unit: WorkUnit, part: Path) -> bool:
    """Whether this worker sees what the test process put in STATE."""
    return bool(STATE.get("in_parent_only"))


def wait_or_fail(unit: WorkUnit, part: Path) -> str:
    """`unit.args` = (seconds, fail): prints a line naming the unit, sleeps, then raises ValueError if `fail`, else
    returns the unit's name (units still running or pending when another fails)."""
    import time

    seconds, fail = unit.args
    print(f"printed by unit {unit.name} in its worker", flush=True)
    time.sleep(seconds)
    if fail:
        raise ValueError(f"unit {unit.name} failed on purpose")
    return unit.name


def scene_file(unit: WorkUnit, part: Path) -> dict:
    """A many-scene job's task (`engine.scene_files`): writes `<scene>.txt` (the dataset root it was given) into
    its part folder and returns the scene's summary entry; a scene whose name starts with "bad" raises ValueError."""
    root, _storage_options, _options = unit.args
    if unit.name.startswith("bad"):
        raise ValueError(f"scene {unit.name} failed on purpose")
    (part / f"{unit.name}.txt").write_text(root)
    return {"file": f"{unit.name}.txt", "frames": len(unit.name)}
