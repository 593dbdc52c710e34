"""Many scenes, one video each: `DIR/<scene>.mp4` for every scene selected, rendered through the scale-out
engine (`nuparquet.engine`: a local process pool, Ray, or this process) with the same bytes whichever runs it.

```python
import nuparquet
result = nuparquet.render_scenes("OUT", nuparquet.SceneSelection(all_scenes=True), "videos", channel="all",
                                 engine="ray")
# the same with option objects: render_scenes("OUT", SceneSelection(...), "videos", RenderOptions(...),
#                                             engine=EngineOptions(...))
```

Each scene's task runs the one-scene `render` (its query reads only that scene: the scene filter is pushed into
the Parquet scans) into the unit's part folder; the commit, the summary (`DIR/render-summary.json`, with a digest
of the options for `--resume`) and the failure rules are the engine's many-scene job
(`nuparquet.engine.scene_files`).
"""

from __future__ import annotations

from nuparquet.dataset.selection import SceneSelection, scene_job
from nuparquet.engine.options import EngineOptions
from nuparquet.engine.run import check_engine
from nuparquet.engine.scene_files import SceneFiles, SceneVerb, write_scene_files
from nuparquet.errors import UsageError
from nuparquet.options import resolve_all
from nuparquet.progress import OnProgress
from nuparquet.rendering.video.options import ALL_CHANNELS, SUMMARY_NAME, RenderOptions

RENDER = SceneVerb("nuparquet.rendering.video.pipeline:render", ".mp4")


def render_scenes(dataset, selection: SceneSelection | None, out, options: RenderOptions | None = None, *,
                  engine: EngineOptions | None = None, on_progress: OnProgress | None = None,
                  **fields) -> SceneFiles:
    """Render every scene of `selection` of `dataset` with `options` into the folder `out`, one video per scene
    (`out/<scene>.mp4`), on `engine`; selection, settings and engine may also be given as keyword fields
    (`all_scenes=True, channel="all", workers=4`). See the module docstring.

    Raises:
        UsageError: bad options, an unknown scene or channel, Ray asked for but not installed.
        QueryError: a bad --where.
        UnitsFailed: scenes failed (each named with its error). Without `engine.keep_going` the first failure
            stops the job and nothing is committed; with it the other scenes are committed first.
    """
    selection, options, engine = resolve_all(fields, (SceneSelection, selection), (RenderOptions, options),
                                             (EngineOptions, engine))
    check_engine(engine)  # Ray installed: say so before anything is read
    dataset, scenes, out_dir = scene_job(dataset, selection, out)
    if options.channel not in (None, ALL_CHANNELS) and options.channel not in dataset.channels.get("cameras", []):
        cameras = ", ".join([*dataset.channels.get("cameras", []), ALL_CHANNELS])
        raise UsageError(f"unknown channel {options.channel!r}; valid channels: {cameras}")
    return write_scene_files(dataset, scenes, out_dir, RENDER, options, engine, summary_name=SUMMARY_NAME,
                             file_key="video", label=f"render {len(scenes)} scene(s)",
                             summary_fields={"channel": options.channel}, on_progress=on_progress)
