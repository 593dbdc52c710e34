"""Many scenes, one video each: `DIR/<scene>.mp4` for every scene selected, rendered through the scale-out
engine (`nuparquet.engine`: a local process pool, Ray, or this process) with the same bytes whichever runs it.

```python
import nuparquet
result = nuparquet.render_scenes("OUT", all_scenes=True, out_dir="videos", channel="all", engine="ray")
# the same with option objects: render_scenes("OUT", SceneSelection(...), RenderOptions(...), EngineOptions(...))
```

Each scene is one work unit: its task opens the dataset (a path or URL every worker can read), runs the
one-scene `render` (its query reads only that scene: the scene filter is pushed into the Parquet scans) and
writes its video into the unit's part folder (`DIR/.nuparquet-parts/`). The commit moves each finished video
into `DIR` (a rename on the same file system) and then writes `DIR/render-summary.json`, which records every
scene rendered there with a digest of the options (`render_settings`); `--resume` skips the scenes it lists
whose video is present and was made with the same options.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import polars as pl

from nuparquet.engine import (
    EngineOptions, UnitOutcome, WorkUnit, check_engine, move_parts, unit_file_name, raise_failures, run_units,
)
from nuparquet.errors import QueryError, UsageError
from nuparquet.options import resolve, split_fields
from nuparquet.atomic import write_text_atomic
from nuparquet.progress import OnProgress
from nuparquet.rendering.options import ALL_CHANNELS, SUMMARY_NAME, RenderOptions, SceneSelection

PARTS_NAME = ".nuparquet-parts"


@dataclass
class BatchResult:
    """What a many-scene render did: `outcomes` in scene order (`UnitOutcome.value` is the scene's entry of
    the summary: video file name, frames written and skipped, size), the folder and the summary written."""

    out_dir: Path
    summary: Path
    outcomes: list[UnitOutcome]

    @property
    def rendered(self) -> list[str]:
        return [o.name for o in self.outcomes if o.ok and not o.resumed]

    @property
    def resumed(self) -> list[str]:
        return [o.name for o in self.outcomes if o.resumed]

    @property
    def failed(self) -> list[str]:
        return [o.name for o in self.outcomes if not o.ok]


def video_name(scene: str) -> str:
    """The file a scene's video is written to inside --out-dir (the scene name, quoted if it is not a plain
    file name)."""
    return f"{unit_file_name(scene)}.mp4"


def select_scenes(dataset, selection: SceneSelection) -> list[str]:
    """The scene names `selection` asks for, sorted by name.

    Raises:
        UsageError: a --scenes name the dataset does not hold (the valid names are listed), nothing selected.
        QueryError: a --where condition polars cannot parse or run.
    """
    if selection.where is not None:
        try:
            condition = pl.sql_expr(selection.where)
            names = dataset.scan("scenes").filter(condition).select("name").collect()["name"].to_list()
        except (pl.exceptions.PolarsError, ValueError) as exc:  # a bad column, a syntax error
            raise QueryError(f"--where {selection.where!r}: {exc}".splitlines()[0]) from None
    else:
        names = dataset.scene_names()
    if selection.scenes:
        dataset.check_scenes(selection.scenes)
        wanted = set(selection.scenes)
        names = [name for name in names if name in wanted]
    if not names:
        raise UsageError("no scene selected" + (f" by --where {selection.where!r}" if selection.where else ""))
    return sorted(set(names))


def render_unit(unit: WorkUnit, part: Path) -> dict:
    """The engine task: render one scene (`unit.name`) into `part/<scene>.mp4`. `unit.args`: (dataset root,
    storage options, RenderOptions). Returns the scene's summary entry."""
    from nuparquet.dataset import open_dataset
    from nuparquet.rendering.pipeline import render

    root, storage_options, options = unit.args
    dataset = open_dataset(root, storage_options=storage_options)
    name = video_name(unit.name)
    result = render(dataset, unit.name, replace(options, out=part / name))
    return {"video": name, "channel": result.channel, "frames_written": result.frames_written,
            "frames_skipped": result.frames_skipped, "width": result.width, "height": result.height,
            "fps": result.fps, "missing": result.missing[:5]}


def render_settings(root: str, options: RenderOptions) -> str:
    """A short digest of what makes a scene's video what it is: the dataset and every render option but the
    scene, the output paths, where the images are read from (`dataroot`: a run resumed after the images moved
    draws the same pictures), `on_missing` and the decode threads. `--resume` reuses only videos made with the
    same."""
    fields = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(options).items()
              if k not in ("out", "frames_dir", "overwrite", "threads", "dataroot", "on_missing")}
    return hashlib.sha256(json.dumps({"dataset": root, **fields}, sort_keys=True, default=str).encode()).hexdigest()[:12]


def _previous_summary(out_dir: Path) -> dict:
    try:
        summary = json.loads((out_dir / SUMMARY_NAME).read_text())
        return summary if isinstance(summary, dict) and isinstance(summary.get("scenes"), dict) else {}
    except (OSError, ValueError):
        return {}


def _write_json(path: Path, value: dict) -> None:
    write_text_atomic(path, json.dumps(value, indent=2, sort_keys=True) + "\n")


def _check(dataset, options: RenderOptions, selection: SceneSelection) -> None:
    selection.check()
    if options.out is not None or options.frames_dir is not None:
        raise UsageError("a many-scene render writes DIR/<scene>.mp4: leave out --out and --frames-dir")
    if options.channel not in (None, ALL_CHANNELS) and options.channel not in dataset.channels.get("cameras", []):
        cameras = ", ".join([*dataset.channels.get("cameras", []), ALL_CHANNELS])
        raise UsageError(f"unknown channel {options.channel!r}; valid channels: {cameras}")
    if not dataset.is_remote:
        from nuparquet.atomic import check_apart

        check_apart(Path(selection.out_dir), dataset.root, what="the converted dataset")


def render_scenes(dataset_or_path, selection: SceneSelection | None = None, options: RenderOptions | None = None,
                  engine: EngineOptions | None = None, *, on_progress: OnProgress | None = None,
                  **fields) -> BatchResult:
    """Render every scene of `selection` with `options` (its `out`, `frames_dir` are not used) into
    `selection.out_dir`, one video per scene, on `engine`; each may also be given as keyword fields (`all_scenes=True,
    out_dir="videos", channel="all", workers=4`). See the module docstring.

    Raises:
        UsageError: bad options, an unknown scene or channel, Ray asked for but not installed.
        QueryError: a bad --where.
        UnitsFailed: scenes failed (each named with its error). Without `engine.keep_going` the first failure
            stops the job and nothing is committed; with it the other scenes are committed first.
    """
    from nuparquet.dataset import as_dataset

    selection_fields, render_fields, engine_fields = split_fields(fields, SceneSelection, RenderOptions, EngineOptions)
    selection = resolve(SceneSelection, selection, selection_fields)
    options = resolve(RenderOptions, options, render_fields)
    engine = resolve(EngineOptions, engine, engine_fields)
    check_engine(engine)
    dataset = as_dataset(dataset_or_path)
    _check(dataset, options, selection)
    scenes = select_scenes(dataset, selection)
    out_dir = Path(selection.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    root = str(dataset.root) if dataset.is_remote else str(Path(dataset.root).resolve())
    options = replace(options, out=None, frames_dir=None)
    settings = render_settings(root, options)
    parts_dir = out_dir / PARTS_NAME / settings  # parts of a run with other options are never resumed
    previous = _previous_summary(out_dir).get("scenes", {})
    present = {name: entry for name, entry in previous.items()
               if isinstance(entry, dict) and (out_dir / str(entry.get("video", ""))).is_file()}
    reusable = {name: entry for name, entry in present.items() if entry.get("settings") == settings}
    units = [WorkUnit(scene, (root, dataset.storage_options, options)) for scene in scenes]
    outcomes = run_units(render_unit, units, parts_dir=parts_dir, options=engine, committed=reusable,
                         on_progress=on_progress, label=f"render {len(scenes)} scene(s)")

    # Commit: finished videos into place (renames within DIR), then the summary that lists them.
    move_parts(outcomes, parts_dir, out_dir, name=lambda index, scene, filename: filename,
               skip=lambda outcome: outcome.resumed and outcome.name in reusable)
    entries = dict(present)  # videos of earlier runs still in DIR stay listed
    entries.update({o.name: {**o.value, "settings": settings} for o in outcomes if o.ok})
    failed = {o.name: o.error for o in outcomes if not o.ok}
    summary = out_dir / SUMMARY_NAME
    _write_json(summary, {"dataset": root, "channel": options.channel, "scenes": entries, "failed": failed})
    if not failed:
        shutil.rmtree(parts_dir, ignore_errors=True)
        try:
            (out_dir / PARTS_NAME).rmdir()  # left when parts of another run's options remain
        except OSError:
            pass
    raise_failures(outcomes)
    return BatchResult(out_dir=out_dir, summary=summary, outcomes=outcomes)
