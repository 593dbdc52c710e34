"""Many scenes, one MCAP file each: `DIR/<scene>.mcap` for every scene selected, written through the scale-out
engine (`nuparquet.engine`: a local process pool, Ray, or this process) with the same bytes whichever runs it.

```python
from nuparquet.engine import EngineOptions
from nuparquet.mcap import McapOptions, McapSelection, export_scenes
result = export_scenes("OUT", McapOptions(scene=""), McapSelection(all_scenes=True, out_dir="mcap"),
                       EngineOptions(engine="ray"))
```

Each scene is one work unit: its task opens the dataset (a path or URL every worker can read) and runs the
one-scene `export_mcap` into the unit's part folder (`DIR/.nuparquet-parts/`). The commit moves each finished file
into `DIR` (a rename on the same file system), then writes `DIR/mcap-summary.json`, which lists every scene
exported there with a digest of the options; `--resume` skips the scenes it lists whose file is present and was
made with the same options.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from nuparquet.engine import (
    EngineOptions, UnitOutcome, WorkUnit, check_engine, move_parts, part_name, raise_failures, run_units,
)
from nuparquet.errors import UsageError
from nuparquet.mcap.options import SUMMARY_NAME, McapOptions, McapSelection
from nuparquet.partials import write_text_atomic
from nuparquet.progress import OnProgress

PARTS_NAME = ".nuparquet-parts"


@dataclass
class BatchResult:
    """What a many-scene export did: `outcomes` in scene order (`UnitOutcome.value` is the scene's summary entry:
    file name, messages per topic, size, missing files), the folder and the summary written."""

    out_dir: Path
    summary: Path
    outcomes: list[UnitOutcome]

    @property
    def exported(self) -> list[str]:
        return [o.name for o in self.outcomes if o.ok and not o.resumed]

    @property
    def resumed(self) -> list[str]:
        return [o.name for o in self.outcomes if o.resumed]

    @property
    def failed(self) -> list[str]:
        return [o.name for o in self.outcomes if not o.ok]


def file_name(scene: str) -> str:
    """The file a scene is written to inside --out-dir (the scene name, quoted if it is not a plain file name)."""
    return f"{part_name(scene)}.mcap"


def export_unit(unit: WorkUnit, part: Path) -> dict:
    """The engine task: export one scene (`unit.name`) into `part/<scene>.mcap`. `unit.args`: (dataset root,
    storage options, McapOptions). Returns the scene's summary entry."""
    from nuparquet.dataset import open_dataset
    from nuparquet.mcap.export import export_mcap

    root, storage_options, options = unit.args
    dataset = open_dataset(root, storage_options=storage_options)
    name = file_name(unit.name)
    result = export_mcap(dataset, replace(options, scene=unit.name, out=part / name))
    return {"file": name, "bytes": result.bytes, "messages": result.messages, "sensor_bytes": result.sensor_bytes,
            "missing": len(result.missing), "first_missing": result.missing[:5]}


def export_settings(root: str, options: McapOptions) -> str:
    """A short digest of what makes a scene's file what it is: the dataset and every option but the scene, the
    output path, where the sensor files are read from and `on_missing`. `--resume` reuses only files made with the
    same."""
    fields = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(options).items()
              if k not in ("scene", "out", "dataroot", "on_missing")}
    text = json.dumps({"dataset": root, **fields}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def _previous_summary(out_dir: Path) -> dict:
    try:
        summary = json.loads((out_dir / SUMMARY_NAME).read_text())
        return summary if isinstance(summary, dict) and isinstance(summary.get("scenes"), dict) else {}
    except (OSError, ValueError):
        return {}


def export_scenes(dataset_or_path, options: McapOptions, selection: McapSelection, engine: EngineOptions | None = None,
                  *, on_progress: OnProgress | None = None) -> BatchResult:
    """Export every scene of `selection` with `options` (its `scene` and `out` are not used) into
    `selection.out_dir`, one MCAP file per scene, on `engine`. See the module docstring.

    Raises:
        UsageError: bad options, an unknown scene, Ray asked for but not installed.
        QueryError: a bad --where.
        UnitsFailed: scenes failed (each named with its error). Without `engine.keep_going` the first failure
            stops the job and nothing is committed; with it the other scenes are committed first.
    """
    from nuparquet.dataset import open_dataset
    from nuparquet.render.batch import select_scenes

    engine = engine or EngineOptions()
    check_engine(engine)
    dataset = dataset_or_path if hasattr(dataset_or_path, "scan") else open_dataset(dataset_or_path)
    selection.check()
    if options.out is not None:
        raise UsageError("a many-scene export writes DIR/<scene>.mcap: leave out --out")
    out_dir = Path(selection.out_dir)
    replace(options, out=out_dir / "x.mcap").check()
    if not dataset.is_remote:
        from nuparquet.partials import check_apart

        check_apart(out_dir, dataset.root, what="the converted dataset")
    scenes = select_scenes(dataset, selection)
    out_dir.mkdir(parents=True, exist_ok=True)
    root = str(dataset.root) if dataset.is_remote else str(Path(dataset.root).resolve())
    options = replace(options, out=None)
    settings = export_settings(root, options)
    parts_dir = out_dir / PARTS_NAME / settings  # parts of a run with other options are never resumed
    previous = _previous_summary(out_dir).get("scenes", {})
    present = {name: entry for name, entry in previous.items()
               if isinstance(entry, dict) and (out_dir / str(entry.get("file", ""))).is_file()}
    reusable = {name: entry for name, entry in present.items() if entry.get("settings") == settings}
    units = [WorkUnit(scene, (root, dataset.storage_options, options)) for scene in scenes]
    outcomes = run_units(export_unit, units, parts_dir=parts_dir, options=engine, committed=reusable,
                         on_progress=on_progress, label=f"export-mcap {len(scenes)} scene(s)")

    # Commit: finished files into place (renames within DIR), then the summary that lists them.
    move_parts(outcomes, parts_dir, out_dir, name=lambda index, scene, filename: filename,
               skip=lambda outcome: outcome.resumed and outcome.name in reusable)
    entries = dict(present)  # files of earlier runs still in DIR stay listed
    entries.update({o.name: {**o.value, "settings": settings} for o in outcomes if o.ok})
    failed = {o.name: o.error for o in outcomes if not o.ok}
    summary = out_dir / SUMMARY_NAME
    write_text_atomic(summary, json.dumps({"dataset": root, "scenes": entries, "failed": failed}, indent=2,
                                          sort_keys=True) + "\n")
    if not failed:
        shutil.rmtree(parts_dir, ignore_errors=True)
        try:
            (out_dir / PARTS_NAME).rmdir()  # left when parts of another run's options remain
        except OSError:
            pass
    raise_failures(outcomes)
    return BatchResult(out_dir=out_dir, summary=summary, outcomes=outcomes)
