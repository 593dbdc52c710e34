"""`nuparquet render OUT --scene NAME [--channel CHANNEL|all|bev] --out scene.mp4`: annotated scene videos (cameras
and / or the bird's-eye view); `nuparquet render OUT --all-scenes --out-dir DIR [--engine ray]`: one video per scene,
in parallel; `nuparquet render OUT --sample TOKEN | --sample-data TOKEN | --annotation TOKEN | --instance TOKEN |
--map LOCATION ... --out picture.png`: one picture (`nuparquet.rendering.pictures.single`).

The flags are generated from `RenderOptions`, `SceneSelection`, `EngineOptions` and `ImageOptions`
(`nuparquet.cli.arguments.add_options`); only `OUT` and `--quiet` are the CLI's own.
"""

from __future__ import annotations

import argparse
import sys

from nuparquet.cli.arguments import add_options, opened, options_from
from nuparquet.cli.progress import bars
from nuparquet.engine.options import EngineOptions
from nuparquet.errors import UsageError
from nuparquet.dataset.selection import SceneSelection
from nuparquet.rendering.pictures.image_options import ImageOptions
from nuparquet.rendering.video.options import RenderOptions
from nuparquet.sensors.options import SensorFiles

_EPILOG = """\
examples:
  nuparquet render OUT --scene scene-0061 --out scene-0061.mp4
  nuparquet render OUT --scene scene-0061 --channel all --all-frames --out scene-0061-cams.mp4
  nuparquet render OUT --scene scene-0061 --lidar --scale 1 --frames-dir frames/ --frame-format png
  nuparquet render OUT --scene scene-0061 --channel bev --out scene-0061-bev.mp4
  nuparquet render OUT --scene scene-0061 --channel all --bev --out scene-0061-cams-bev.mp4
  nuparquet render OUT --all-scenes --out-dir videos/ --channel all            # local processes, every core
  nuparquet render OUT --where "log_location = 'singapore-onenorth'" --out-dir videos/ --engine ray
  nuparquet render s3://bucket/OUT --all-scenes --out-dir /shared/videos --engine ray --ray-address auto
one picture (PNG or JPEG):
  nuparquet render OUT --sample-data TOKEN --out cam.png                   # a camera image with its boxes
  nuparquet render OUT --sample-data TOKEN --nsweeps 5 --out lidar.png     # a lidar or radar frame from above
  nuparquet render OUT --sample-data TOKEN --lidar-color lidarseg --lidarseg-legend --filter-lidarseg-labels 17,24 \
      --lidarseg-preds preds.bin --out seg.png                             # predictions beside the ground truth
  nuparquet render OUT --sample TOKEN --out sample.jpg                     # every sensor of a sample
  nuparquet render OUT --sample TOKEN --pointcloud-in-image --camera-channel CAM_BACK --out points.png
  nuparquet render OUT --sample TOKEN --map-in-image --out map-in-image.png
  nuparquet render OUT --annotation TOKEN --extra-info --out ann.png;  nuparquet render OUT --instance TOKEN --out i.png
  nuparquet render OUT --map boston-seaport --map-patch 300,1000,500,1200 --out patch.png
  nuparquet render OUT --map boston-seaport --map-mask 400,1100,100,100 --map-angle 45 --map-layers lane,walkway --out m.png
  nuparquet render OUT --map boston-seaport --ego-poses --scenes scene-0061 --out poses.png

Channel names come from the dataset (`nuparquet info OUT`); --channel all tiles every camera, front row over
back row; --channel bev is the bird's-eye view (map layers when map/ was converted, reference-lidar points
coloured by height or --lidar-color, boxes with their heading, the ego; --bev-up north|ego, --bev-range-m), and --bev
adds it beside the cameras of --channel all. The MP4 is H.264 (yuv420p, index at the front), so web browsers
play it. Images are read from the dataroot the dataset was converted from (manifest.json, source.dataroot)
unless --dataroot says otherwise. Missing or unreadable image files are named; by default those frames are
skipped (a placeholder tile in the mosaic) and counted in a warning at the end. Exit codes: 0 done, 1 input problem (--on-missing error,
nothing renderable), 2 bad arguments (unknown scene or channel: the valid names are listed).

Many scenes (--all-scenes, --scenes, --where) write DIR/<scene>.mp4 and DIR/render-summary.json; the videos
are the same bytes whichever --engine renders them. A failing scene is named with its error: the job stops
and commits nothing, or with --keep-going the other scenes are written and the exit code is 1. --resume
skips scenes already rendered into DIR (or finished by a run that stopped on a failure).

One picture (--sample, --sample-data, --annotation, --instance, --map) is drawn as nuscenes-devkit's render_sample,
render_sample_data, render_annotation, render_instance and its map renderers draw it (their boxes, colours and axes),
with OpenCV, and written to --out as PNG or JPEG. Sample-data frames of lidar and radar are seen from above in the
devkit's flat ego frame (x forward to the right), --axes-limit metres each way, the map underneath.
"""


def register(sub) -> None:
    p = sub.add_parser(
        "render",
        help="render a scene's cameras and/or bird's-eye view with 3D boxes into an MP4 video or image files, or one "
        "sample, sample_data, annotation, instance or map picture",
        description="Draw the annotated 3D boxes of one scene onto its camera images (projected exactly as "
        "nuscenes-devkit does; category colours, the front face marked with a thicker outline and a cross, "
        "boxes drawn far to near) and/or its bird's-eye view (--channel bev, --bev: map layers, lidar points, boxes, "
        "the ego), and write an H.264 MP4 and/or one image per frame (with a frame index, frames.parquet). Or draw "
        "one picture of a sample, sample_data, annotation, instance or map (--sample, --sample-data, --annotation, "
        "--instance, --map). Headless: no window opens.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dataset", metavar="OUT", help="a directory written by `nuparquet convert`")
    p.add_argument("--scene", metavar="NAME", help="the scene to render, e.g. scene-0061 (`nuparquet info OUT` "
                   "lists them); or many scenes with --all-scenes, --scenes or --where")
    p.add_argument("--out", metavar="FILE", help="the video to write (FILE.mp4); for one picture (--sample, "
                   "--sample-data, --annotation, --instance, --map) the PNG or JPEG")
    p.add_argument("--frames-dir", metavar="DIR", help="also (or instead) write each frame as an image: "
                   "DIR/00000.jpg, ..., with DIR/frames.parquet saying which sample_data each frame shows")
    add_options(p, RenderOptions, defaults={"scale": None})
    add_options(p, SensorFiles)
    add_options(p, SceneSelection)
    p.add_argument("--out-dir", metavar="DIR", help="where a many-scene render writes DIR/<scene>.mp4 and its summary")
    add_options(p, EngineOptions)
    add_options(p, ImageOptions)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


# The render flags a picture of one thing uses (the rest are for scene videos): --scale, --labels, --lidar-color
# (and --overwrite, harmless: a picture is always replaced).
_PICTURE_FLAGS = ("scale", "labels", "lidar_color", "overwrite")


def _video_flags_given(args) -> list[str]:
    """The flags only scene videos take that differ from their defaults (a picture refuses them)."""
    import dataclasses

    given = []
    for f in dataclasses.fields(RenderOptions):
        if f.metadata.get("cli") and f.name not in _PICTURE_FLAGS and getattr(args, f.name) != f.default:
            given.append(f.metadata.get("flag") or "--" + f.name.replace("_", "-"))
    return given + (["--frames-dir"] if args.frames_dir is not None else [])


def _render_options(args) -> RenderOptions:
    return options_from(args, RenderOptions, unset=("scale",))


def run(args) -> int:
    image = options_from(args, ImageOptions, unset=("scale",), scenes=tuple(args.scenes or ()))
    if image.wanted:
        return _run_image(args, image)
    selection = options_from(args, SceneSelection)
    if selection.many or args.out_dir is not None:
        return _run_many(args, selection)
    if args.scene is None:
        raise UsageError("say what to render: --scene NAME (with --out or --frames-dir), or --all-scenes, "
                         "--scenes A,B or --where SQL with --out-dir DIR")
    from nuparquet.rendering.video.pipeline import render  # cv2 and PyAV load only when rendering

    result = render(opened(args), args.scene, args.out, _render_options(args), frames_dir=args.frames_dir,
                    on_progress=bars(not args.quiet))
    targets = [str(t) for t in (result.out, result.frames_dir) if t is not None]
    print(
        f"rendered {result.frames_written} frame(s) of {result.scene} {result.channel} "
        f"({result.width}x{result.height}, {result.fps:g} fps) -> {', '.join(targets)}"
    )
    if result.missing:
        print(
            f"warning: {len(result.missing)} file(s) missing or unreadable, {result.frames_skipped} frame(s) "
            f"skipped (the frame before repeated, to keep the timing); first: {result.missing[0]}",
            file=sys.stderr,
        )
    return 0


def _run_many(args, selection: SceneSelection) -> int:
    from nuparquet.engine import UnitsFailed
    from nuparquet.rendering.video.batch import render_scenes

    if args.scene is not None:
        raise UsageError("--scene renders one scene; with --all-scenes, --scenes or --where leave it out")
    if args.out is not None or args.frames_dir is not None:
        raise UsageError("a many-scene render writes DIR/<scene>.mp4: leave out --out and --frames-dir")
    if not selection.many:
        raise UsageError("--out-dir: say which scenes to take (--all-scenes, --scenes A,B or --where SQL)")
    from nuparquet.engine.run import check_engine

    engine = options_from(args, EngineOptions)
    check_engine(engine)  # Ray installed: say so before the dataset is opened
    try:
        result = render_scenes(opened(args), selection, args.out_dir, _render_options(args), engine=engine,
                               on_progress=bars(not args.quiet))
    except UnitsFailed as exc:
        done = [o for o in exc.outcomes if o is not None and o.ok]
        if done and args.keep_going:
            print(f"rendered {len(done)} scene(s) -> {args.out_dir}")
        raise
    resumed = f" ({len(result.resumed)} already done, skipped)" if result.resumed else ""
    print(f"rendered {len(result.written)} scene(s){resumed} -> {result.out_dir} (summary: {result.summary.name})")
    return 0


def _run_image(args, image: ImageOptions) -> int:
    """One picture to --out (PNG or JPEG)."""
    from nuparquet.rendering.pictures.image_options import check_image_path

    if args.scene is not None or args.all_scenes or args.out_dir is not None or args.where is not None:
        raise UsageError("one picture (--sample, --sample-data, --annotation, --instance, --map) or scenes (--scene, "
                         "--all-scenes, --where), not both")
    if args.out is None:
        raise UsageError("give --out PICTURE.png (or .jpg) for the picture")
    video_only = _video_flags_given(args)
    if video_only:
        raise UsageError(f"{', '.join(video_only)}: for scene videos; a picture of one thing takes none of them")
    image.check()
    out = check_image_path(args.out)
    from nuparquet.rendering.pictures.single import render_image, save_image  # cv2 loads only when drawing

    picture = render_image(opened(args), image)
    save_image(picture, out)
    print(f"rendered {picture.shape[1]}x{picture.shape[0]} -> {out}")
    return 0
