"""`build_report`: a converted dataset as a static site that opens from disk with no network.

```python
from nuparquet.site import ReportOptions, build_report
result = build_report("OUT", SceneSelection(scenes=("scene-0061",)), "report", ReportOptions(stills=2),
                      on_progress=print)
```

Layout of DIR:
    index.html                      dataset facts, the scene table (sorts, filters), charts, statistics tables
    scenes/<scene>.html             one page per scene: facts, video, keyframe renderings, CAN bus plots, categories
    scenes/<scene>/                 its keyframe renderings (still-0.jpg, ...) and CAN bus plots (PNG)
    videos/<scene>.mp4              every camera tiled with the bird's-eye view, H.264 (and render-summary.json)
    assets/report.css, report.js    the only style and script (hand-written, no library)
    assets/plots/*.png              the charts of `nuparquet stats --plots`

The statistics are the canned queries (`nuparquet.queries.summary`), the charts `nuparquet.rendering.pictures.charts`; the videos are
rendered through the many-scene render (`render.batch.render_scenes`: the engine, Ray included) and the scene
assets through the same engine (`report.scene_assets`). The folder is written beside DIR and renamed into place
when complete (`--overwrite` replaces an existing one).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from urllib.parse import quote

import polars as pl

from nuparquet.dataset.selection import SceneSelection
from nuparquet.engine import EngineOptions, UnitsFailed, check_engine, unit_file_name
from nuparquet.errors import UsageError
from nuparquet.options import resolve_all
from nuparquet.progress import OnProgress, Reporter
from nuparquet.site import facts as report_facts
from nuparquet.site import pages
from nuparquet.site.options import ReportOptions

VIDEO_DIR = "videos"
SCENE_DIR = "scenes"
ASSET_FILES = ("report.css", "report.js")


@dataclass
class ReportResult:
    """What a report holds: its folder, the scenes (pages), and per scene the video entry of the render summary
    (None when not rendered) and the keyframe renderings and plots written; `problems`: scene -> why something is
    missing (a video or renderings that could not be made)."""

    out: Path
    scenes: list[str]
    videos: dict[str, dict | None]
    assets: dict[str, dict]
    problems: dict[str, str] = field(default_factory=dict)

    @property
    def index(self) -> Path:
        return self.out / "index.html"

    def page(self, scene: str) -> Path:
        return self.out / SCENE_DIR / f"{unit_file_name(scene)}.html"


def _statistics(dataset, scenes: list[str] | None) -> tuple[list[tuple[str, str, pl.DataFrame]], dict]:
    """(name, title, result) of every default `stats` section but the scene list (the scene table shows it)."""
    from nuparquet.queries.sections import BY_NAME, summary

    lazy = summary(dataset, scene=scenes)
    results = dict(zip(lazy, pl.collect_all(list(lazy.values()))))
    return [(name, BY_NAME[name].title, result) for name, result in results.items() if name != "scenes"], results


def _copy_assets(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    source = resources.files("nuparquet.site") / "assets"
    for name in ASSET_FILES:
        (folder / name).write_bytes((source / name).read_bytes())


def _videos(dataset, scenes: list[str], options: ReportOptions, engine: EngineOptions, out_dir: Path,
            on_progress) -> tuple[dict[str, dict | None], dict[str, str]]:
    """Every scene's video through the many-scene render (every camera tiled with the bird's-eye view when the
    dataset has a lidar); a scene that fails is reported, not fatal."""
    from nuparquet.dataset.selection import SceneSelection
    from nuparquet.rendering.video.batch import render_scenes
    from nuparquet.rendering.video.options import RenderOptions

    bev = dataset.channels.get("reference_lidar") is not None
    render_options = RenderOptions(channel="all", bev=bev, scale=options.video_scale)
    try:
        outcomes = render_scenes(dataset, SceneSelection(scenes=tuple(scenes)), out_dir, render_options,
                                 engine=replace(engine, keep_going=True, resume=False), on_progress=on_progress).outcomes
    except UnitsFailed as exc:
        outcomes = [o for o in exc.outcomes if o is not None]
    videos = {o.name: (o.value if o.ok else None) for o in outcomes}
    problems = {o.name: f"video: {o.error}" for o in outcomes if not o.ok}
    return videos, problems


def _scene_assets(dataset, scenes: list[str], options: ReportOptions, engine: EngineOptions, out_dir: Path,
                  on_progress) -> tuple[dict[str, dict], dict[str, str]]:
    """Keyframe renderings and CAN bus plots of every scene (`scene_assets` through the many-scene helper),
    committed into `out_dir/<scene>/`."""
    from nuparquet.channels import default_camera
    from nuparquet.engine.scene_files import SceneVerb, write_scene_files
    from nuparquet.site.scene_assets import SceneAssetOptions

    channels = dataset.channels
    can_bus = {"can_bus/vehicle_monitor", "can_bus/pose", "can_bus/steeranglefeedback"} <= set(dataset.datasets)
    wanted = SceneAssetOptions(stills=options.stills if options.videos else 0,
                               camera=default_camera(channels.get("cameras", []), channels.get("camera_layout")),
                               lidar=channels.get("reference_lidar") is not None, can_bus=can_bus)
    if not (wanted.stills or can_bus):
        return {}, {}
    try:
        outcomes = write_scene_files(dataset, scenes, out_dir, SceneVerb("nuparquet.site.scene_assets:scene_assets", ""),
                                     wanted, replace(engine, keep_going=True, resume=False), summary_name=None,
                                     file_key="", label=f"report {len(scenes)} scene page(s)",
                                     on_progress=on_progress).outcomes
    except UnitsFailed as exc:
        outcomes = [o for o in exc.outcomes if o is not None]
    assets = {o.name: o.value for o in outcomes if o.ok}
    problems = {o.name: f"scene assets: {o.error}" for o in outcomes if not o.ok}
    for name, value in assets.items():
        if value.get("stills_error"):
            problems[name] = f"keyframe renderings: {value['stills_error']}"
    return assets, problems


def build_report(dataset, selection: SceneSelection | None = None, out=None, options: ReportOptions | None = None, *,
                 engine: EngineOptions | None = None, on_progress: OnProgress | None = None,
                 **fields) -> ReportResult:
    """Write the report of the scenes of `selection` (default: every scene) of `dataset` into the folder `out`, with
    `options` (or keyword fields of `SceneSelection`, `ReportOptions`, `EngineOptions`: `where=...`, `stills=2`,
    `workers=2`; see the module docstring). Scenes whose video or renderings cannot be made (their images missing)
    get a page saying why; the report is still written.

    Raises:
        UsageError: bad options, no `out`, an unknown scene, DIR exists without --overwrite, no dataroot for the
            videos.
        QueryError: a bad --where.
    """
    from nuparquet.atomic import atomic_directory, check_apart, check_target
    from nuparquet.dataset import as_dataset, select_scenes
    from nuparquet.queries import class_distribution
    from nuparquet.rendering.pictures import charts

    selection, options, engine = resolve_all(fields, (SceneSelection, selection), (ReportOptions, options),
                                             (EngineOptions, engine))
    check_engine(engine)
    if out is None:
        raise UsageError("give the folder to write the report into (--out DIR)")
    selection.check(default_all=True)
    dataset = as_dataset(dataset)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file; give a directory")
    if not dataset.is_remote:
        check_apart(out, dataset.root, what="the converted dataset")
    check_target(out, overwrite=options.overwrite)
    scenes = select_scenes(dataset, selection.scenes, selection.where)
    has_cameras = bool(dataset.channels.get("cameras"))
    if options.videos and has_cameras and not dataset.sensors.embeds("camera"):
        # the images come from the dataroot unless the output embeds them (`convert --embed camera`)
        dataset.sensors.root("the camera images", otherwise=", or --no-videos for a report without videos and "
                             "keyframe renderings")
    scope = scenes if selection.subset else None

    with Reporter(on_progress, "report", total=5, unit="step") as reporter, \
            atomic_directory(out, overwrite=options.overwrite) as tmp:
        _copy_assets(tmp / "assets")
        reporter.advance(step="statistics")
        sections, results = _statistics(dataset, scope)
        chart_paths = charts.write_plots(dataset, tmp / "assets" / "plots", scene=scope, results=results)
        scene_rows = report_facts.scene_table(dataset, scenes)
        categories = class_distribution(dataset, by_scene=True, scene=scenes).collect()
        reporter.advance(step="videos")
        videos: dict[str, dict | None] = {s: None for s in scenes}
        problems: dict[str, str] = {}
        if options.videos and has_cameras:
            found, failed = _videos(dataset, scenes, options, engine, tmp / VIDEO_DIR, on_progress)
            videos.update(found)
            problems.update(failed)
        reporter.advance(step="scene assets")
        assets, failed = _scene_assets(dataset, scenes, options, engine, tmp / SCENE_DIR, on_progress)
        for scene, reason in failed.items():
            problems[scene] = f"{problems[scene]}; {reason}" if scene in problems else reason
        reporter.advance(step="pages")
        title = f"{dataset.version or 'dataset'} — {len(scenes)} scene(s)"
        note = (f"This report covers {len(scenes)} selected scene(s); the statistics and charts are of those scenes."
                if selection.subset else "")
        charts = [(f"assets/plots/{p.name}", p.stem.replace("_", " ")) for p in chart_paths]
        (tmp / "index.html").write_text(pages.index_page(title, report_facts.dataset_facts(dataset), sections, charts,
                                                         scene_rows, max_rows=options.max_rows, note=note))
        (tmp / SCENE_DIR).mkdir(exist_ok=True)
        for row in scene_rows.iter_rows(named=True):
            name = row["name"]
            entry = assets.get(name, {})
            video = videos.get(name)
            page = pages.scene_page(
                row, video=video, video_error=problems.get(name) if options.videos else None,
                stills=entry.get("stills", []), stills_error=entry.get("stills_error") or problems.get(name),
                plots=entry.get("plots", []),
                categories=categories.filter(pl.col("scene_name") == name).drop("scene_name"),
                max_rows=options.max_rows, assets=quote(unit_file_name(name)))
            (tmp / SCENE_DIR / f"{unit_file_name(name)}.html").write_text(page)
        (tmp / "report.json").write_text(json.dumps({"scenes": scenes, "videos": videos, "assets": assets,
                                                     "problems": problems}, indent=2, sort_keys=True) + "\n")
        reporter.advance(step="done")
    return ReportResult(out=out, scenes=scenes, videos=videos, assets=assets, problems=problems)
