"""`nuparquet export-mcap OUT --scene NAME --out scene.mcap`: one scene as an MCAP file for Foxglove;
`nuparquet export-mcap OUT --all-scenes --out-dir DIR [--engine ray]`: one file per scene, in parallel.

The flags are generated from `McapOptions`, `SceneSelection` and `EngineOptions`
(`nuparquet.cli.arguments.add_options`); only `OUT` and `--quiet` are the CLI's own.
"""

from __future__ import annotations

import argparse
import sys

from nuparquet.cli.arguments import add_options, opened, options_from
from nuparquet.cli.progress import bars
from nuparquet.engine.options import EngineOptions
from nuparquet.sensors.options import SensorFiles
from nuparquet.errors import UsageError
from nuparquet.dataset.selection import SceneSelection
from nuparquet.mcap.options import SUMMARY_NAME, McapOptions

_EPILOG = f"""\
examples:
  nuparquet export-mcap OUT --scene scene-0061 --out scene-0061.mcap
  nuparquet export-mcap OUT --scene scene-0061 --out small.mcap --without images,points --boxes keyframes
  nuparquet export-mcap OUT --all-scenes --out-dir mcap/                     # local processes, every core
  nuparquet export-mcap OUT --where "log_location = 'boston-seaport'" --out-dir mcap/ --engine ray

Open the file in Foxglove (File > Open local file): it needs no configuration. Topics, in Foxglove's published
schemas (protobuf):
  /tf                              FrameTransforms: map -> base_link (ego pose) and base_link -> CHANNEL, per frame
  /CHANNEL/image_rect_compressed   CompressedImage: each camera's JPEG files as they are
  /CHANNEL/camera_info             CameraCalibration: the intrinsics, per image
  /CHANNEL                         PointCloud: every lidar and radar sweep (lidarseg/panoptic labels as fields
                                   when converted with them), in the sensor frame
  /markers/annotations             SceneUpdate: the 3D boxes (category, instance) at keyframes and, with --boxes
                                   camera, at the default camera's frames between them (interpolated like the
                                   devkit's get_boxes)
  /map                             SceneUpdate: the map layers around the route (when map/ was converted)
  /can_bus/MESSAGE                 JSON: the CAN bus messages (when converted), every field plottable
Timestamps are the data's, in microseconds, exactly; messages are in log-time order, in zstd-compressed chunks.
Points come from lidar_points/ and radar_points/ when converted, else from the files under the dataroot recorded
at conversion (--dataroot to override). Missing sensor files are named; by default their messages are left out
and counted in a warning. Exit codes: 0 done, 1 input problem (--on-missing error), 2 bad arguments.

Many scenes (--all-scenes, --scenes, --where) write DIR/<scene>.mcap and DIR/{SUMMARY_NAME}; the files are the
same bytes whichever --engine writes them. --keep-going and --resume work as for `nuparquet render`.
"""


def register(sub) -> None:
    p = sub.add_parser(
        "export-mcap",
        help="write a scene (or many) as an MCAP file to open in Foxglove",
        description="Write one scene's cameras, lidar and radar sweeps, ego and sensor transforms, 3D boxes, map "
        "and CAN bus into one MCAP file that Foxglove opens without configuration.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dataset", metavar="OUT", help="a directory written by `nuparquet convert`")
    p.add_argument("--scene", metavar="NAME", help="the scene to export, e.g. scene-0061 (`nuparquet info OUT` lists "
                   "them); or many scenes with --all-scenes, --scenes or --where")
    p.add_argument("--out", metavar="FILE.mcap", help="the MCAP file to write (replaced if it exists)")
    add_options(p, McapOptions)
    add_options(p, SensorFiles)
    add_options(p, SceneSelection)
    p.add_argument("--out-dir", metavar="DIR", help="where a many-scene export writes DIR/<scene>.mcap and its summary")
    add_options(p, EngineOptions)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    selection = options_from(args, SceneSelection)
    if selection.many or args.out_dir is not None:
        return _run_many(args, selection)
    if args.scene is None:
        raise UsageError("say what to export: --scene NAME with --out FILE.mcap, or --all-scenes, --scenes A,B or "
                         "--where SQL with --out-dir DIR")
    from nuparquet.mcap.export import export_mcap

    if args.out is None:
        raise UsageError("nothing to write: give --out FILE.mcap")
    result = export_mcap(opened(args), args.scene, args.out, options_from(args, McapOptions),
                         on_progress=bars(not args.quiet))
    print(f"wrote {result.total_messages} message(s) on {len(result.messages)} topic(s) of {result.scene} -> "
          f"{result.out} ({result.bytes / 1e6:.1f} MB)")
    if result.missing:
        print(f"warning: {len(result.missing)} sensor file(s) missing or unreadable, their messages left out; "
              f"first: {result.missing[0]}", file=sys.stderr)
    return 0


def _run_many(args, selection: SceneSelection) -> int:
    from nuparquet.engine import UnitsFailed
    from nuparquet.mcap.batch import export_scenes

    if args.scene is not None:
        raise UsageError("--scene exports one scene; with --all-scenes, --scenes or --where leave it out")
    if args.out is not None:
        raise UsageError("a many-scene export writes DIR/<scene>.mcap: leave out --out")
    if not selection.many:
        raise UsageError("--out-dir: say which scenes to take (--all-scenes, --scenes A,B or --where SQL)")
    try:
        result = export_scenes(opened(args), selection, args.out_dir, options_from(args, McapOptions),
                               engine=options_from(args, EngineOptions), on_progress=bars(not args.quiet))
    except UnitsFailed as exc:
        done = [o for o in exc.outcomes if o is not None and o.ok]
        if done and args.keep_going:
            print(f"exported {len(done)} scene(s) -> {args.out_dir}")
        raise
    resumed = f" ({len(result.resumed)} already done, skipped)" if result.resumed else ""
    missing = sum(o.value.get("missing", 0) for o in result.outcomes if o.ok and isinstance(o.value, dict))
    print(f"exported {len(result.written)} scene(s){resumed} -> {result.out_dir} (summary: {result.summary.name})")
    if missing:
        print(f"warning: {missing} sensor file(s) missing or unreadable, their messages left out (see "
              f"{result.summary.name})", file=sys.stderr)
    return 0
