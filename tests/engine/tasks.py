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


class SceneFileResult:
    """What `scene_file` wrote: its summary entry names the file and counts the scene name's letters."""

    def __init__(self, scene: str):
        self.scene = scene

    def summary_entry(self, file_name: str) -> dict:
        return {"file": file_name, "frames": len(self.scene)}


def scene_file(dataset, scene: str, out: Path, options) -> SceneFileResult:
    """A one-scene verb for the many-scene job (`engine.scene_files`): writes `out` (`<scene>.txt`) holding the
    dataset root it was opened from; a scene whose name starts with "bad" raises ValueError."""
    if scene.startswith("bad"):
        raise ValueError(f"scene {scene} failed on purpose")
    out.write_text(str(dataset.root))
    return SceneFileResult(scene)
