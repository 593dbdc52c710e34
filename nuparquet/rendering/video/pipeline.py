"""The render job: one scene, one camera (or every camera tiled), boxes drawn on every output frame, into an
H.264 MP4 and/or a folder of images.

```python
import nuparquet
result = nuparquet.render("OUT", "scene-0061", "scene-0061.mp4", channel="all", on_progress=print)
```

The stages, one module each (STYLE.md: vectorise over the batch; the only Python loop is over output frames):

1. `scene`: one polars query for the scene's camera frames, annotations and samples (and lidar keyframes).
2. The cameras of those frames, built once from the stored transforms and resized to the tile
   (`nuparquet.geometry.camera`), and every box projected into them once (`overlay`).
3. `plan`: which camera frame goes into which tile of which output, and the tile sources (`camera_tile`).
4. `loop`: tiles decoded a few outputs ahead (`decode`), drawn (`draw`), composed (`mosaic`) and written
   (`sink`, `video`).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nuparquet.dataset import as_dataset
from nuparquet.errors import InputError, UsageError
from nuparquet.frames.boxes import frame_boxes
from nuparquet.frames.poses import cameras_from_frames
from nuparquet.options import resolve
from nuparquet.progress import OnProgress, Reporter
from nuparquet.rendering import draw
from nuparquet.rendering.video.camera_tile import CameraTile
from nuparquet.rendering.video.loop import render_frames
from nuparquet.rendering.video.options import BEV_CHANNEL, RenderOptions, check_targets
from nuparquet.rendering.overlay import DrawStyle, build_overlay
from nuparquet.rendering.plan import TilePlan, camera_rows_per_output, tile_size
from nuparquet.rendering.video.scene import SceneRows, cameras_to_render, load_scene, reference_lidar
from nuparquet.rendering.video.sink import FrameSink
from nuparquet.rendering.video.video import even_size
from nuparquet.sensors.reader import inside

__all__ = ["RenderOptions", "RenderResult", "render"]


@dataclass
class RenderResult:
    """What a render wrote: `frames_written` pictures, one per output time (so picture n is at n / fps), of which
    `frames_skipped` had nothing new to show and repeat the picture before; `missing` lists the image files that
    were missing or unreadable. The frame index (`frame_index`) says which sample_data each picture shows."""

    scene: str
    channel: str
    frames_written: int
    frames_skipped: int
    width: int
    height: int
    fps: float
    out: Path | None
    frames_dir: Path | None
    missing: list[str] = field(default_factory=list)

    def summary_entry(self, file_name: str) -> dict:
        """This scene's entry in a many-scene render's summary (`render-summary.json`)."""
        return {"video": file_name, "channel": self.channel, "frames_written": self.frames_written,
                "frames_skipped": self.frames_skipped, "width": self.width, "height": self.height, "fps": self.fps,
                "missing": self.missing[:5]}


def _image_path(dataroot: Path, filename: str) -> str:
    """The image file of a frame; a filename that leaves the dataroot is refused (`sensors.reader.inside`): it is
    reported as unreadable under a name that says why."""
    path = inside(dataroot, filename)
    return str(path) if path is not None else f"{dataroot / filename} (outside the dataroot: refused)"


def camera_plan(rows: SceneRows, layout, dataroot: Path, *, scale: float, mosaic: bool, all_frames: bool,
                fps: float, clip: bool = False, labels: str = "category", dataset=None,
                lidar_color: str = "depth", predictions=None, lidar_predictions=None) -> TilePlan:
    """The tile plan of a camera render: the cameras built and every box projected once, one `CameraTile` per
    camera of `layout` (rows of channel names). `scale`: output size / image size; the other arguments as in
    `RenderOptions`; `dataset` (a Dataset) lets lidar points come from its lidar_points/; `predictions`
    (`rendering.predictions.Predictions`) are drawn over the keyframes."""
    cameras = rows.cameras
    size = tile_size(cameras, scale)
    tile_cameras = cameras_from_frames(cameras).resized_to(size)
    boxes = frame_boxes(cameras, rows.annotations, rows.samples)
    overlay = build_overlay(tile_cameras, boxes, clip=clip, labels=labels)
    lidar = None
    if rows.lidar.height:
        from nuparquet.rendering.points import LidarPoints  # the point cloud path loads only when points are drawn

        lidar = LidarPoints.build(tile_cameras, cameras, rows.lidar, dataroot, dataset=dataset, color=lidar_color,
                                  predictions=lidar_predictions)
    channels = [channel for row in layout for channel in row]
    times_us, plan_rows = camera_rows_per_output(cameras, rows.samples, channels, mosaic=mosaic,
                                                 all_frames=all_frames, fps=fps)
    paths = [_image_path(dataroot, name) for name in cameras["filename"].to_list()]
    image_size_px = np.stack([cameras["width"].to_numpy(), cameras["height"].to_numpy()], axis=1)
    decode_scale = np.max(tile_cameras.scale, axis=1)  # the decoded image must cover the tile on both axes
    style = DrawStyle.for_scale(scale)
    predicted, predicted_style, predicted_legend = None, None, ()
    if predictions is not None:
        from nuparquet.rendering.predictions import prediction_boxes, prediction_style

        boxes, rows = prediction_boxes(cameras, predictions)
        predicted = build_overlay(tile_cameras, boxes, clip=clip, colors_rgb=predictions.colors_rgb(rows),
                                  texts=predictions.labels(rows))
        predicted_style = prediction_style(style)
        predicted_legend = tuple(predictions.legend())
    tokens, stamps = tuple(cameras["token"].to_list()), cameras["timestamp"].to_numpy()
    tiles = iter(CameraTile(channel, plan_rows[:, column], paths, decode_scale, size, overlay, style, lidar,
                            image_size_px, predicted, predicted_style, tokens, stamps,
                            prediction_legend=predicted_legend)
                 for column, channel in enumerate(channels))
    return TilePlan(times_us, tuple(tuple(next(tiles) for _ in row) for row in layout), size)


def _bev_view(options: RenderOptions, size: tuple[int, int]):
    from nuparquet.rendering.bev import View

    return View(size, options.bev_range_m, ego_up=options.bev_up == "ego")


def bev_plan(dataset, rows: SceneRows, options: RenderOptions, dataroot: Path,
             predictions=None) -> tuple[TilePlan, float]:
    """`--channel bev`: one square tile per reference-lidar keyframe (or frame), and the video's frame rate (the
    lidar's own with --all-frames unless --fps says otherwise)."""
    from nuparquet.rendering.video.bev_scene import bev_source

    size = (options.bev_size, options.bev_size)
    tile, times_us = bev_source(dataset, rows, dataroot, _bev_view(options, size), lidar_color=options.lidar_color,
                                predictions=predictions, lidar_predictions=options.lidar_predictions)
    fps = options.frame_rate
    if options.fps is None and options.all_frames and len(times_us) > 1:
        fps = float(round(1e6 / float(np.median(np.diff(times_us)))))
    return TilePlan(times_us, ((tile,),), size), fps


def with_bev_tile(plan: TilePlan, dataset, rows: SceneRows, options: RenderOptions, dataroot: Path,
                  predictions=None) -> TilePlan:
    """The camera plan with the bird's-eye view appended to its first row, at the camera tile size."""
    from nuparquet.rendering.video.bev_scene import bev_source

    tile, _ = bev_source(dataset, rows, dataroot, _bev_view(options, plan.tile_size), times_us=plan.times_us,
                         lidar_color=options.lidar_color, predictions=predictions,
                         lidar_predictions=options.lidar_predictions)
    layout = (plan.layout[0] + (tile,),) + plan.layout[1:]
    return TilePlan(plan.times_us, layout, plan.tile_size)


def render(dataset, scene: str, out=None, options: RenderOptions | None = None, *, frames_dir=None,
           on_progress: OnProgress | None = None, **fields) -> RenderResult:
    """Render `scene` of `dataset` (a `Dataset` or a path) into the video `out` (FILE.mp4) and/or one image per
    picture into `frames_dir`, as `options` (or keyword fields of `RenderOptions`) describe; see the module
    docstring. Progress goes to `on_progress` (one "frame" unit per output picture).

    Raises:
        UsageError: bad options, nothing to write, unknown scene or channel, no dataroot with the images, --lidar
            without a lidar.
        InputError: with on_missing="error", the first missing or unreadable file (named by path); with
            "skip", when no frame at all could be rendered.
    """
    options = resolve(RenderOptions, options, fields)
    check_targets(out, frames_dir, options.overwrite)
    dataset = as_dataset(dataset)
    if not dataset.is_remote:  # never write into the converted dataset (--out OUT/manifest.json replaced it)
        from nuparquet.atomic import check_apart

        for target in (out, frames_dir):
            if target is not None:
                check_apart(target, dataset.root, what="the converted dataset")
    dataroot = dataset.sensors.root("the camera images")
    if options.labels == "none":
        plan, channel, fps = _plan(dataset, scene, options, dataroot)
    else:  # the query and projections run beside the start of OpenCV's text engine on this (the drawing) thread
        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="nuparquet-plan") as side:
            planned = side.submit(_plan, dataset, scene, options, dataroot)
            draw.start_text()
            plan, channel, fps = planned.result()

    out = Path(out) if out is not None else None
    frames_dir = Path(frames_dir) if frames_dir is not None else None

    def make_sink(executor) -> FrameSink:
        return FrameSink(executor, size=plan.size, fps=fps, video=out, crf=options.crf,
                         preset=options.preset, frames_dir=frames_dir, frame_format=options.frame_format)

    with Reporter(on_progress, f"render {scene} {channel}", total=len(plan), unit="frame") as reporter:
        result = render_frames(plan, make_sink, on_missing=options.on_missing, threads=options.threads,
                               reporter=reporter)
    if result.written == result.skipped:  # nothing drawn at all (the sink wrote nothing)
        raise InputError(
            f"no frame of {scene} {channel} could be rendered: all {len(result.missing)} image "
            f"file(s) are missing or unreadable, e.g. {result.missing[0] if result.missing else '?'} "
            "(is --dataroot right?)"
        )
    width, height = even_size(*plan.size) if out is not None else plan.size
    return RenderResult(scene=scene, channel=channel, frames_written=result.written,
                        frames_skipped=result.skipped, width=width, height=height, fps=fps,
                        out=out, frames_dir=frames_dir, missing=result.missing)


def _plan(dataset, scene: str, options: RenderOptions, dataroot: Path) -> tuple[TilePlan, str, float]:
    """The scene's query and every tile's plan: (plan, the channel as reported, the video's frame rate)."""
    dataset.check_scenes([scene])
    fps = options.frame_rate
    predictions = None
    if options.predictions is not None:
        from nuparquet.rendering.predictions import load_predictions

        predictions = load_predictions(options.predictions, dataset, scene, options.score_threshold)
    bev_channel = reference_lidar(dataset) if options.channel == BEV_CHANNEL or options.bev else None
    if options.channel == BEV_CHANNEL:
        channel = BEV_CHANNEL
        rows = load_scene(dataset, scene, (), all_frames=options.all_frames, bev_channel=bev_channel)
        _check_bev_rows(rows, scene, bev_channel)
        plan, fps = bev_plan(dataset, rows, options, dataroot, predictions)
    else:
        channel, layout = cameras_to_render(dataset, options.channel)
        rows = load_scene(dataset, scene, [c for row in layout for c in row], all_frames=options.all_frames,
                          lidar_channel=reference_lidar(dataset) if options.draws_lidar else None,
                          bev_channel=bev_channel, channel_label=channel)
        plan = camera_plan(rows, layout, dataroot, scale=options.scale, mosaic=options.mosaic,
                           all_frames=options.all_frames, fps=fps, clip=options.clip,
                           labels=options.labels, dataset=dataset, lidar_color=options.lidar_color,
                           predictions=predictions, lidar_predictions=options.lidar_predictions)
        if options.bev:
            _check_bev_rows(rows, scene, bev_channel)
            plan = with_bev_tile(plan, dataset, rows, options, dataroot, predictions)
    return plan, channel, fps


def _check_bev_rows(rows: SceneRows, scene: str, lidar_channel: str) -> None:
    if rows.bev_lidar.height == 0:
        raise UsageError(f"{scene} has no {lidar_channel} frame to centre the bird's-eye view on")
