"""Many scenes, one file each, through the engine: what `render --all-scenes` (one video per scene) and
`export-mcap --all-scenes` (one MCAP file per scene) share.

Each scene is one work unit: its task opens the dataset (a path or URL every worker can read), writes the scene's
file into the unit's part folder (`DIR/.nuparquet-parts/<settings>/`) and returns the scene's summary entry. The
commit moves each finished file into `DIR` (a rename on the same file system) and then writes the summary
(`DIR/<summary name>`), which records every scene written there with a digest of the options (`settings`);
`--resume` skips the scenes it lists whose file is present and was made with the same options.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

from nuparquet.atomic import check_apart, write_text_atomic
from nuparquet.engine.options import EngineOptions
from nuparquet.engine.run import check_engine, raise_failures, run_units
from nuparquet.engine.commit import move_parts
from nuparquet.engine.units import Task, UnitOutcome, WorkUnit, unit_file_name
from nuparquet.progress import OnProgress

PARTS_NAME = ".nuparquet-parts"


@dataclass
class SceneFiles:
    """What a many-scene job did: `outcomes` in scene order (`UnitOutcome.value`: the scene's summary entry), the
    folder and the summary written."""

    out_dir: Path
    summary: Path
    outcomes: list[UnitOutcome]

    @property
    def written(self) -> list[str]:
        return [o.name for o in self.outcomes if o.ok and not o.resumed]

    @property
    def resumed(self) -> list[str]:
        return [o.name for o in self.outcomes if o.resumed]

    @property
    def failed(self) -> list[str]:
        return [o.name for o in self.outcomes if not o.ok]


def scene_file_name(scene: str, suffix: str) -> str:
    """The file a scene is written to inside the output folder: the scene name (quoted if it is not a plain file
    name) and `suffix` (".mp4", ".mcap")."""
    return f"{unit_file_name(scene)}{suffix}"


def settings_digest(root: str, options, leave_out: Iterable[str]) -> str:
    """A short digest of what makes a scene's file what it is: the dataset and every option but those of
    `leave_out` (output paths, where inputs are read from, error handling, threads)."""
    skipped = set(leave_out)
    fields = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(options).items() if k not in skipped}
    return hashlib.sha256(json.dumps({"dataset": root, **fields}, sort_keys=True, default=str).encode()).hexdigest()[:12]


def _previous_summary(out_dir: Path, summary_name: str) -> dict:
    try:
        summary = json.loads((out_dir / summary_name).read_text())
        return summary if isinstance(summary, dict) and isinstance(summary.get("scenes"), dict) else {}
    except (OSError, ValueError):
        return {}


def write_scene_files(dataset, scenes: list[str], out_dir: Path, task: Task, options, engine: EngineOptions, *,
                      summary_name: str, file_key: str, leave_out: Iterable[str], label: str,
                      summary_fields: dict | None = None, on_progress: OnProgress | None = None,
                      settings: Callable[[str], str] | None = None) -> SceneFiles:
    """Run `task` on every scene of `scenes` (unit args: dataset root, storage options, `options`) on `engine`,
    commit each finished file into `out_dir` and write the summary `out_dir/summary_name`: {"dataset", **summary_fields,
    "scenes": {scene: entry + settings}, "failed": {scene: error}}. An entry names its file under `file_key`.

    Raises:
        UsageError: Ray asked for but not installed, `out_dir` inside the dataset.
        UnitsFailed: scenes failed (each named with its error). Without `engine.keep_going` the first failure stops
            the job and nothing is committed; with it the other scenes are committed first.
    """
    check_engine(engine)
    if not dataset.is_remote:
        check_apart(out_dir, dataset.root, what="the converted dataset")
    out_dir.mkdir(parents=True, exist_ok=True)
    root = str(dataset.root) if dataset.is_remote else str(Path(dataset.root).resolve())
    digest = settings(root) if settings else settings_digest(root, options, leave_out)
    parts_dir = out_dir / PARTS_NAME / digest  # parts of a run with other options are never resumed
    previous = _previous_summary(out_dir, summary_name).get("scenes", {})
    present = {name: entry for name, entry in previous.items()
               if isinstance(entry, dict) and (out_dir / str(entry.get(file_key, ""))).is_file()}
    reusable = {name: entry for name, entry in present.items() if entry.get("settings") == digest}
    units = [WorkUnit(scene, (root, dataset.storage_options, options)) for scene in scenes]
    outcomes = run_units(task, units, parts_dir=parts_dir, options=engine, committed=reusable,
                         on_progress=on_progress, label=label)

    # Commit: finished files into place (renames within the folder), then the summary that lists them.
    move_parts(outcomes, parts_dir, out_dir, name=lambda index, scene, filename: filename,
               skip=lambda outcome: outcome.resumed and outcome.name in reusable)
    entries = dict(present)  # files of earlier runs still in the folder stay listed
    entries.update({o.name: {**o.value, "settings": digest} for o in outcomes if o.ok})
    failed = {o.name: o.error for o in outcomes if not o.ok}
    summary = out_dir / summary_name
    write_text_atomic(summary, json.dumps({"dataset": root, **(summary_fields or {}), "scenes": entries,
                                           "failed": failed}, indent=2, sort_keys=True) + "\n")
    if not failed:
        shutil.rmtree(parts_dir, ignore_errors=True)
        try:
            (out_dir / PARTS_NAME).rmdir()  # left when parts of another run's options remain
        except OSError:
            pass
    raise_failures(outcomes)
    return SceneFiles(out_dir=out_dir, summary=summary, outcomes=outcomes)
