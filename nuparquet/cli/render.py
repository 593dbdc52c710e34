"""`nuparquet render OUT --scene NAME --channel CAM_FRONT|...|all --out scene.mp4`: annotated scene videos."""

from __future__ import annotations

import argparse
import sys

from nuparquet.render.options import ALL_CHANNELS, CAMERA_CHANNELS, DEFAULT_CRF, FRAME_FORMATS, LABEL_MODES, ON_MISSING, RenderOptions

_EPILOG = """\
examples:
  nuparquet render OUT --scene scene-0061 --channel CAM_FRONT --out scene-0061.mp4
  nuparquet render OUT --scene scene-0061 --channel all --all-frames --out scene-0061-6cams.mp4
  nuparquet render OUT --scene scene-0061 --channel CAM_FRONT --lidar --scale 1 --frames-dir frames/ --frame-format png

The MP4 is H.264 (yuv420p, index at the front), so web browsers play it. Images are read from the dataroot the
dataset was converted from (manifest.json, source.dataroot) unless --dataroot says otherwise. Missing or
unreadable image files are named; by default those frames are skipped (a placeholder tile in the mosaic) and
counted in a warning at the end. Exit codes: 0 done, 1 input problem (--on-missing error, nothing renderable),
2 bad arguments (unknown scene or channel: the valid names are listed).
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
    p.add_argument("--scene", required=True, help="scene name, e.g. scene-0061 (`nuparquet info OUT` lists them)")
    p.add_argument(
        "--channel",
        default="CAM_FRONT",
        metavar="CHANNEL",
        help=f"camera to render: {', '.join(CAMERA_CHANNELS)}, or '{ALL_CHANNELS}' for the six tiled 3x2 "
        "(front-left, front, front-right over back-left, back, back-right). Default: CAM_FRONT",
    )
    p.add_argument("--out", metavar="FILE.mp4", help="the video to write")
    p.add_argument("--frames-dir", metavar="DIR", help="also (or instead) write each frame as an image: DIR/00000.jpg, ...")
    p.add_argument("--frame-format", choices=FRAME_FORMATS, default="jpg", help="image format for --frames-dir (default jpg)")
    p.add_argument(
        "--all-frames",
        action="store_true",
        help="every camera frame (~12 Hz, boxes interpolated between keyframes as the devkit does) instead of "
        "keyframes only (2 Hz). Needs the sweeps/ images",
    )
    p.add_argument(
        "--fps",
        type=float,
        help="frames per second of the video (default 2, or 12 with --all-frames). With --channel all "
        "--all-frames it is also the rate at which the six cameras are sampled (devkit render_scene)",
    )
    p.add_argument("--scale", type=float, default=0.5, help="output size relative to the 1600x900 images (default 0.5; 1 = full size)")
    p.add_argument("--crf", type=int, default=DEFAULT_CRF, help=f"x264 quality, 0 (lossless) .. 51; lower is larger (default {DEFAULT_CRF})")
    p.add_argument("--lidar", action="store_true", help="draw the keyframe LIDAR_TOP points, coloured by depth, into keyframe images")
    p.add_argument("--labels", choices=LABEL_MODES, default="category", help="box labels: category name, track (short instance token) or none (default category)")
    p.add_argument(
        "--clip",
        action="store_true",
        help="clip box edges at the camera's near plane (z = 0.1 m) so boxes partly behind the camera are "
        "drawn in part; by default they are left out, as the devkit does",
    )
    p.add_argument(
        "--on-missing",
        choices=ON_MISSING,
        default="skip",
        help="a missing or unreadable image file: skip the frame and warn at the end (default), or stop with exit 1",
    )
    p.add_argument("--dataroot", metavar="PATH", help="where the images are, if not at the dataroot recorded at conversion")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.render.pipeline import render  # cv2 and PyAV load only when rendering

    options = RenderOptions(
        scene=args.scene,
        channel=args.channel,
        out=args.out,
        frames_dir=args.frames_dir,
        all_frames=args.all_frames,
        fps=args.fps,
        scale=args.scale,
        crf=args.crf,
        lidar=args.lidar,
        labels=args.labels,
        clip=args.clip,
        frame_format=args.frame_format,
        on_missing=args.on_missing,
        dataroot=args.dataroot,
        progress=not args.quiet,
    )
    result = render(args.dataset, options)
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
