"""Many scenes, one output each, through the engine: the one helper that runs a one-scene verb over many scenes,
shared by `render --all-scenes` (a video per scene), `export-mcap --all-scenes` (an MCAP file per scene) and
`report` (its videos and scene pages).

A one-scene verb `verb(dataset, scene, out, options)` names its output by its argument and holds its settings in
`options`; so each scene is one work unit whose task reopens the dataset (`Dataset.reference`: a path or URL
every worker can read), runs the verb with `out` in the unit's part folder (`DIR/.nuparquet-parts/<settings>/`),
and returns the result's summary entry. The commit moves each finished output into `DIR` (a rename on the same
file system) and then writes the summary (`DIR/<summary name>`), which records every scene written there with a
digest of the dataset and the whole options object (`settings`); `--resume` skips the scenes it lists whose
output is present and was made with the same settings.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path

from nuparquet.atomic import check_apart, write_text_atomic
from nuparquet.engine.options import EngineOptions
from nuparquet.engine.run import check_engine, raise_failures, run_units
from nuparquet.engine.commit import move_parts
from nuparquet.engine.units import UnitOutcome, WorkUnit, unit_file_name
from nuparquet.progress import OnProgress

PARTS_NAME = ".nuparquet-parts"


@dataclass
class SceneFiles:
    """What a many-scene job did: `outcomes` in scene order (`UnitOutcome.value`: the scene's summary entry), the
    folder and the summary written."""

    out_dir: Path
    summary: Path | None
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


def settings_digest(root: str, options) -> str:
    """A short digest of what makes a scene's output what it is: the dataset and the options object (settings only:
    where it is written is the verb's argument, never an option)."""
    fields = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(options).items()}
    return hashlib.sha256(json.dumps({"dataset": root, **fields}, sort_keys=True, default=str).encode()).hexdigest()[:12]


@dataclass(frozen=True)
class SceneVerb:
    """A one-scene verb the many-scene job runs in its workers: `function` ("module:name", imported there) called as
    `function(dataset, scene, out, options)`, whose result has `summary_entry(file name) -> dict`; `suffix` names
    the output (`<scene><suffix>`: ".mp4", ".mcap"; "" for a folder)."""

    function: str
    suffix: str

    def __call__(self, *args):
        module, name = self.function.split(":")
        return getattr(importlib.import_module(module), name)(*args)


def scene_unit(unit: WorkUnit, part: Path) -> dict:
    """The engine task of every many-scene job: `unit.args` = (DatasetReference, SceneVerb, options). Runs the verb
    on scene `unit.name` into `part/<scene><suffix>`; returns the scene's summary entry."""
    reference, verb, options = unit.args
    name = scene_file_name(unit.name, verb.suffix)
    return verb(reference.open(), unit.name, part / name, options).summary_entry(name)


def _previous_summary(out_dir: Path, summary_name: str) -> dict:
    try:
        summary = json.loads((out_dir / summary_name).read_text())
        return summary if isinstance(summary, dict) and isinstance(summary.get("scenes"), dict) else {}
    except (OSError, ValueError):
        return {}


def write_scene_files(dataset, scenes: list[str], out_dir: Path, verb: SceneVerb, options, engine: EngineOptions, *,
                      summary_name: str | None, file_key: str, label: str, summary_fields: dict | None = None,
                      on_progress: OnProgress | None = None) -> SceneFiles:
    """Run the one-scene `verb` with `options` on every scene of `scenes` on `engine`, commit each finished output
    into `out_dir` (`out_dir/<scene><suffix>`) and write the summary `out_dir/summary_name`: {"dataset",
    **summary_fields, "scenes": {scene: entry + settings}, "failed": {scene: error}}. An entry names its output under
    `file_key`. With `summary_name` None (a report's parts) nothing is resumed and no summary is written.

    Raises:
        UsageError: Ray asked for but not installed, `out_dir` inside the dataset.
        UnitsFailed: scenes failed (each named with its error). Without `engine.keep_going` the first failure stops
            the job and nothing is committed; with it the other scenes are committed first.
    """
    check_engine(engine)
    if not dataset.is_remote:
        check_apart(out_dir, dataset.root, what="the converted dataset")
    out_dir.mkdir(parents=True, exist_ok=True)
    reference = dataset.reference
    digest = settings_digest(reference.root, options)
    parts_dir = out_dir / PARTS_NAME / digest  # parts of a run with other options are never resumed
    previous = _previous_summary(out_dir, summary_name).get("scenes", {}) if summary_name else {}
    present = {name: entry for name, entry in previous.items()
               if isinstance(entry, dict) and (out_dir / str(entry.get(file_key, ""))).exists()}
    reusable = {name: entry for name, entry in present.items() if entry.get("settings") == digest}
    units = [WorkUnit(scene, (reference, verb, options)) for scene in scenes]
    outcomes = run_units(scene_unit, units, parts_dir=parts_dir, options=engine, committed=reusable,
                         on_progress=on_progress, label=label)

    # Commit: finished outputs into place (renames within the folder), then the summary that lists them.
    move_parts(outcomes, parts_dir, out_dir, name=lambda index, scene, filename: filename,
               skip=lambda outcome: outcome.resumed and outcome.name in reusable)
    failed = {o.name: o.error for o in outcomes if not o.ok}
    summary = out_dir / summary_name if summary_name else None
    if summary is not None:
        entries = dict(present)  # outputs of earlier runs still in the folder stay listed
        entries.update({o.name: {**o.value, "settings": digest} for o in outcomes if o.ok})
        write_text_atomic(summary, json.dumps({"dataset": reference.root, **(summary_fields or {}),
                                               "scenes": entries, "failed": failed}, indent=2, sort_keys=True) + "\n")
    if not failed or summary is None:
        shutil.rmtree(parts_dir, ignore_errors=True)
        try:
            (out_dir / PARTS_NAME).rmdir()  # left when parts of another run's options remain
        except OSError:
            pass
    raise_failures(outcomes)
    return SceneFiles(out_dir=out_dir, summary=summary, outcomes=outcomes)
