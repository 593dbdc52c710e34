"""`nuparquet synth OUT --scenes N [--samples-per-scene K] [--with-images] [--with-lidar] [--seed S] [--version V]`.
The flags come from `nuparquet.synth.options.SynthOptions`."""

from __future__ import annotations

import sys
import time

from nuparquet.cli.arguments import add_options, options_from
from nuparquet.synth.options import SynthOptions


def register(sub) -> None:
    p = sub.add_parser(
        "synth",
        help="write a deterministic synthetic dataset in the exact nuScenes layout",
        description="Write a synthetic nuScenes-format dataroot to OUT: OUT/VERSION/*.json (all 13 tables: "
        "12 sensor channels with real nuScenes names and calibration style, 2 Hz keyframes, camera/lidar/radar "
        "sweeps at ~12/20/13 Hz, a smoothly driving ego car, moving and parked objects of the nuScenes "
        "categories with per-instance tracks), OUT/maps/*.png, the map expansion (OUT/maps/expansion/<location>.json: "
        "roads, lanes with arcline paths and connectivity, walkways, crossings, dividers along the driven roads) "
        "and the CAN bus expansion (OUT/can_bus/). With --with-images every camera frame is a "
        "1600x900 JPEG showing each box as a filled cuboid in its category's colour; with --with-lidar every "
        "LIDAR_TOP frame is a .pcd.bin (points on the boxes and the ground) and every radar frame a .pcd, and "
        "every LIDAR_TOP keyframe has nuScenes-lidarseg and Panoptic nuScenes labels (lidarseg/, panoptic/, "
        "VERSION/lidarseg.json, panoptic.json; category.json gains the lidarseg classes). "
        "The same arguments always give byte-identical tables. The result loads in nuscenes-devkit and in "
        "`nuparquet convert OUT --version VERSION`.",
    )
    p.add_argument("out", metavar="OUT", help="dataroot to write (created if missing; OUT/VERSION is replaced)")
    add_options(p, SynthOptions)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.cli.progress import bars
    from nuparquet.synth import synthesize

    options = options_from(args, SynthOptions)
    start = time.perf_counter()
    dataroot = synthesize(args.out, options, on_progress=bars(not args.quiet))
    files = [kind for kind, on in (("images", options.with_images), ("lidar/radar", options.with_lidar)) if on]
    print(f"wrote {dataroot / options.version}: {options.scenes} scenes x {options.samples_per_scene} samples"
          f"{' with ' + ' and '.join(files) if files else ' (tables only)'} in {time.perf_counter() - start:.1f} s",
          file=sys.stderr if args.quiet else sys.stdout)
    return 0
