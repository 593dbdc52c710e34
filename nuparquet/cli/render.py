"""`nuparquet render OUT --scene NAME [--channel CHANNEL|all] --out scene.mp4`: annotated scene videos.

The flags are generated from `RenderOptions` (`nuparquet.cli.arguments.add_options`); only `OUT` and
`--quiet` are the CLI's own.
"""

from __future__ import annotations

import argparse
import sys

from nuparquet.cli.arguments import add_options, options_from
from nuparquet.cli.progress import bars
from nuparquet.render.options import RenderOptions

_EPILOG = """\
examples:
  nuparquet render OUT --scene scene-0061 --out scene-0061.mp4
  nuparquet render OUT --scene scene-0061 --channel all --all-frames --out scene-0061-cams.mp4
  nuparquet render OUT --scene scene-0061 --lidar --scale 1 --frames-dir frames/ --frame-format png
  nuparquet render OUT --scene scene-0061 --channel bev --out scene-0061-bev.mp4
  nuparquet render OUT --scene scene-0061 --channel all --bev --out scene-0061-cams-bev.mp4

Channel names come from the dataset (`nuparquet info OUT`); --channel all tiles every camera, front row over
back row; --channel bev is the bird's-eye view (map layers when map/ was converted, reference-lidar points
coloured by height, boxes with their heading, the ego vehicle; --bev-up north|ego, --bev-range-m), and --bev
adds it beside the cameras of --channel all. The MP4 is H.264 (yuv420p, index at the front), so web browsers
play it. Images are read from the dataroot the dataset was converted from (manifest.json, source.dataroot)
unless --dataroot says otherwise. Missing or unreadable image files are named; by default those frames are
skipped (a placeholder tile in the mosaic) and counted in a warning at the end. Exit codes: 0 done, 1 input problem (--on-missing error,
nothing renderable), 2 bad arguments (unknown scene or channel: the valid names are listed).
"""


def register(sub) -> None:
    p = sub.add_parser(
        "render",
        help="render a scene's camera images with 3D boxes into an MP4 video or image files",
        description="Draw the annotated 3D boxes of one scene onto its camera images (projected exactly as "
        "nuscenes-devkit does; category colours, the front face marked with a thicker outline and a cross, "
        "boxes drawn far to near) and write an H.264 MP4 and/or one image per frame. Headless: no window opens.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dataset", metavar="OUT", help="a directory written by `nuparquet convert`")
    add_options(p, RenderOptions)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.render.pipeline import render  # cv2 and PyAV load only when rendering

    result = render(args.dataset, options_from(args, RenderOptions), on_progress=bars(not args.quiet))
    targets = [str(t) for t in (result.out, result.frames_dir) if t is not None]
    print(
        f"rendered {result.frames_written} frame(s) of {result.scene} {result.channel} "
        f"({result.width}x{result.height}, {result.fps:g} fps) -> {', '.join(targets)}"
    )
    if result.missing:
        print(
            f"warning: {len(result.missing)} file(s) missing or unreadable, {result.frames_skipped} frame(s) "
            f"skipped; first: {result.missing[0]}",
            file=sys.stderr,
        )
    return 0
