"""Many scenes, one video each: `DIR/<scene>.mp4` for every scene selected, rendered through the scale-out
engine (`nuparquet.engine`: a local process pool, Ray, or this process) with the same bytes whichever runs it.

```python
import nuparquet
result = nuparquet.render_scenes("OUT", all_scenes=True, out_dir="videos", channel="all", engine="ray")
# the same with option objects: render_scenes("OUT", SceneSelection(...), RenderOptions(...), EngineOptions(...))
```

Each scene's task runs the one-scene `render` (its query reads only that scene: the scene filter is pushed into
the Parquet scans) into the unit's part folder; the commit, the summary (`DIR/render-summary.json`, with a digest
of the options for `--resume`) and the failure rules are the engine's many-scene job
(`nuparquet.engine.scene_files`).
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
from nuparquet.options import resolve, split_fields
from nuparquet.progress import OnProgress
from nuparquet.rendering.options import ALL_CHANNELS, SUMMARY_NAME, RenderOptions

# Options that do not change a video's pixels: a --resume may reuse videos made with other values of these.
NOT_SETTINGS = ("out", "frames_dir", "overwrite", "threads", "dataroot", "on_missing")


def render_unit(unit: WorkUnit, part: Path) -> dict:
    """The engine task: render one scene (`unit.name`) into `part/<scene>.mp4`. `unit.args`: (dataset root,
    storage options, RenderOptions). Returns the scene's summary entry."""
    from nuparquet.dataset import open_dataset
    from nuparquet.rendering.pipeline import render

    root, storage_options, options = unit.args
    dataset = open_dataset(root, storage_options=storage_options)
    name = scene_file_name(unit.name, ".mp4")
    result = render(dataset, unit.name, replace(options, out=part / name))
    return {"video": name, "channel": result.channel, "frames_written": result.frames_written,
            "frames_skipped": result.frames_skipped, "width": result.width, "height": result.height,
            "fps": result.fps, "missing": result.missing[:5]}


def render_scenes(dataset_or_path, selection: SceneSelection | None = None, options: RenderOptions | None = None,
                  engine: EngineOptions | None = None, *, on_progress: OnProgress | None = None,
                  **fields) -> SceneFiles:
    """Render every scene of `selection` with `options` (its `out` and `frames_dir` are not used) into
    `selection.out_dir`, one video per scene, on `engine`; each may also be given as keyword fields (`all_scenes=True,
    out_dir="videos", channel="all", workers=4`). See the module docstring.

    Raises:
        UsageError: bad options, an unknown scene or channel, Ray asked for but not installed.
        QueryError: a bad --where.
        UnitsFailed: scenes failed (each named with its error). Without `engine.keep_going` the first failure
            stops the job and nothing is committed; with it the other scenes are committed first.
    """
    from nuparquet.dataset import as_dataset, select_scenes

    selection_fields, render_fields, engine_fields = split_fields(fields, SceneSelection, RenderOptions, EngineOptions)
    selection = resolve(SceneSelection, selection, selection_fields)
    options = resolve(RenderOptions, options, render_fields)
    engine = resolve(EngineOptions, engine, engine_fields)
    check_engine(engine)  # Ray installed: say so before anything is read
    dataset = as_dataset(dataset_or_path)
    selection.check()
    if options.out is not None or options.frames_dir is not None:
        raise UsageError("a many-scene render writes DIR/<scene>.mp4: leave out --out and --frames-dir")
    if options.channel not in (None, ALL_CHANNELS) and options.channel not in dataset.channels.get("cameras", []):
        cameras = ", ".join([*dataset.channels.get("cameras", []), ALL_CHANNELS])
        raise UsageError(f"unknown channel {options.channel!r}; valid channels: {cameras}")
    scenes = select_scenes(dataset, selection.scenes, selection.where)
    return write_scene_files(dataset, scenes, Path(selection.out_dir), render_unit, options, engine,
                             summary_name=SUMMARY_NAME, file_key="video", leave_out=NOT_SETTINGS,
                             label=f"render {len(scenes)} scene(s)", summary_fields={"channel": options.channel},
                             on_progress=on_progress)
