"""Many scenes, one MCAP file each: `DIR/<scene>.mcap` for every scene selected, written through the scale-out
engine (`nuparquet.engine`: a local process pool, Ray, or this process) with the same bytes whichever runs it.

```python
import nuparquet
result = nuparquet.export_mcap_scenes("OUT", all_scenes=True, out_dir="mcap", engine="ray")
```

Each scene's task runs the one-scene `export_mcap` into the unit's part folder; the commit, the summary
(`DIR/mcap-summary.json`, with a digest of the options for `--resume`) and the failure rules are the engine's
many-scene job (`nuparquet.engine.scene_files`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from nuparquet.dataset.selection import SceneSelection
from nuparquet.engine.options import EngineOptions
from nuparquet.engine.run import check_engine
from nuparquet.engine.scene_files import SceneFiles, scene_file_name, write_scene_files
from nuparquet.engine.units import WorkUnit
from nuparquet.errors import UsageError
from nuparquet.mcap.options import SUMMARY_NAME, McapOptions
from nuparquet.options import resolve, split_fields
from nuparquet.progress import OnProgress

# Options that do not change a file's bytes: a --resume may reuse files made with other values of these.
NOT_SETTINGS = ("out", "dataroot", "on_missing")


def export_unit(unit: WorkUnit, part: Path) -> dict:
    """The engine task: export one scene (`unit.name`) into `part/<scene>.mcap`. `unit.args`: (dataset root,
    storage options, McapOptions). Returns the scene's summary entry."""
    from nuparquet.dataset import open_dataset
    from nuparquet.mcap.export import export_mcap

    root, storage_options, options = unit.args
    dataset = open_dataset(root, storage_options=storage_options)
    name = scene_file_name(unit.name, ".mcap")
    result = export_mcap(dataset, unit.name, replace(options, out=part / name))
    return {"file": name, "bytes": result.bytes, "messages": result.messages, "sensor_bytes": result.sensor_bytes,
            "missing": len(result.missing), "first_missing": result.missing[:5]}


def export_scenes(dataset_or_path, selection: SceneSelection | None = None, options: McapOptions | None = None,
                  engine: EngineOptions | None = None, *, on_progress: OnProgress | None = None,
                  **fields) -> SceneFiles:
    """Export every scene of `selection` with `options` (its `out` is not used) into `selection.out_dir`, one MCAP
    file per scene, on `engine`; each may also be given as keyword fields. See the module docstring.

    Raises:
        UsageError: bad options, an unknown scene, Ray asked for but not installed.
        QueryError: a bad --where.
        UnitsFailed: scenes failed (each named with its error). Without `engine.keep_going` the first failure
            stops the job and nothing is committed; with it the other scenes are committed first.
    """
    from nuparquet.dataset import as_dataset, select_scenes

    selection_fields, mcap_fields, engine_fields = split_fields(fields, SceneSelection, McapOptions, EngineOptions)
    selection = resolve(SceneSelection, selection, selection_fields)
    options = resolve(McapOptions, options, mcap_fields)
    engine = resolve(EngineOptions, engine, engine_fields)
    check_engine(engine)  # Ray installed: say so before anything is read
    dataset = as_dataset(dataset_or_path)
    selection.check()
    if options.out is not None:
        raise UsageError("a many-scene export writes DIR/<scene>.mcap: leave out --out")
    scenes = select_scenes(dataset, selection.scenes, selection.where)
    return write_scene_files(dataset, scenes, Path(selection.out_dir), export_unit, options, engine,
                             summary_name=SUMMARY_NAME, file_key="file", leave_out=NOT_SETTINGS,
                             label=f"export-mcap {len(scenes)} scene(s)", on_progress=on_progress)
