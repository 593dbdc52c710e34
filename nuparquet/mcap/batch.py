"""Many scenes, one MCAP file each: `DIR/<scene>.mcap` for every scene selected, written through the scale-out
engine (`nuparquet.engine`: a local process pool, Ray, or this process) with the same bytes whichever runs it.

```python
import nuparquet
result = nuparquet.export_mcap_scenes("OUT", nuparquet.SceneSelection(all_scenes=True), "mcap", engine="ray")
```

Each scene's task runs the one-scene `export_mcap` into the unit's part folder; the commit, the summary
(`DIR/mcap-summary.json`, with a digest of the options for `--resume`) and the failure rules are the engine's
many-scene job (`nuparquet.engine.scene_files`).
"""

from __future__ import annotations

from nuparquet.dataset.selection import SceneSelection, scene_job
from nuparquet.engine.options import EngineOptions
from nuparquet.engine.run import check_engine
from nuparquet.engine.scene_files import SceneFiles, SceneVerb, write_scene_files
from nuparquet.mcap.options import SUMMARY_NAME, McapOptions
from nuparquet.options import resolve_all
from nuparquet.progress import OnProgress

EXPORT = SceneVerb("nuparquet.mcap.export:export_mcap", ".mcap")


def export_scenes(dataset, selection: SceneSelection | None, out, options: McapOptions | None = None, *,
                  engine: EngineOptions | None = None, on_progress: OnProgress | None = None,
                  **fields) -> SceneFiles:
    """Export every scene of `selection` of `dataset` with `options` into the folder `out`, one MCAP file per scene
    (`out/<scene>.mcap`), on `engine`; each may also be given as keyword fields. See the module docstring.

    Raises:
        UsageError: bad options, an unknown scene, Ray asked for but not installed.
        QueryError: a bad --where.
        UnitsFailed: scenes failed (each named with its error). Without `engine.keep_going` the first failure
            stops the job and nothing is committed; with it the other scenes are committed first.
    """
    selection, options, engine = resolve_all(fields, (SceneSelection, selection), (McapOptions, options),
                                             (EngineOptions, engine))
    check_engine(engine)  # Ray installed: say so before anything is read
    dataset, scenes, out_dir = scene_job(dataset, selection, out)
    return write_scene_files(dataset, scenes, out_dir, EXPORT, options, engine, summary_name=SUMMARY_NAME,
                             file_key="file", label=f"export-mcap {len(scenes)} scene(s)", on_progress=on_progress)
