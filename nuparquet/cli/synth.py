"""`nuparquet synth OUT --scenes N [--samples-per-scene K] [--with-images] [--with-lidar] [--seed S] [--version V]`."""

from __future__ import annotations

import sys
import time

from nuparquet.errors import UsageError


def register(sub) -> None:
    p = sub.add_parser(
        "synth",
        help="write a deterministic synthetic dataset in the exact nuScenes layout",
        description="Write a synthetic nuScenes-format dataroot to OUT: OUT/VERSION/*.json (all 13 tables: "
        "12 sensor channels with real nuScenes names and calibration style, 2 Hz keyframes, camera/lidar/radar "
        "sweeps at ~12/20/13 Hz, a smoothly driving ego car, moving and parked objects of the nuScenes "
        "categories with per-instance tracks) and OUT/maps/*.png. With --with-images every camera frame is a "
        "1600x900 JPEG showing each box as a filled cuboid in its category's colour; with --with-lidar every "
        "LIDAR_TOP frame is a .pcd.bin (points on the boxes and the ground) and every radar frame a .pcd, and "
        "every LIDAR_TOP keyframe has nuScenes-lidarseg and Panoptic nuScenes labels (lidarseg/, panoptic/, "
        "VERSION/lidarseg.json, panoptic.json; category.json gains the lidarseg classes). "
        "The same arguments always give byte-identical tables. The result loads in nuscenes-devkit and in "
        "`nuparquet convert OUT --version VERSION`.",
    )
    p.add_argument("out", metavar="OUT", help="dataroot to write (created if missing; OUT/VERSION is replaced)")
    p.add_argument("--scenes", type=int, required=True, help="number of scenes (850 is nuScenes trainval scale)")
    p.add_argument("--samples-per-scene", type=int, default=40,
                   help="keyframes per scene at 2 Hz (default 40: 20 s scenes like nuScenes)")
    p.add_argument("--with-images", action="store_true",
                   help="write the camera JPEGs of all keyframes and sweeps (slow: ~36 JPEGs per sample)")
    p.add_argument("--with-lidar", action="store_true",
                   help="write the lidar .pcd.bin and radar .pcd files of all keyframes and sweeps, and lidarseg/panoptic "
                   "labels of the lidar keyframes")
    p.add_argument("--no-can-bus", dest="can_bus", action="store_false",
                   help="leave out the CAN bus expansion (by default can_bus/ holds every scene's files but the last's)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0); same seed, same dataset")
    p.add_argument("--version", default="v1.0-synth", help="version folder name (default v1.0-synth)")
    p.add_argument("--profile", choices=("regular", "irregular"), default="regular",
                   help="regular (default), or irregular: the cases regular data lacks, for tests (tracks with "
                   "1-3 s gaps, hills, boxes and lidar points just in front of CAM_FRONT, frames on the 10 Hz "
                   "clock, a late first CAM_FRONT frame, and a VERSION-test folder with empty annotation tables)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.cli.progress import bars
    from nuparquet.synth import synthesize

    if args.scenes < 1:
        raise UsageError(f"--scenes must be at least 1, got {args.scenes}")
    if args.samples_per_scene < 1:
        raise UsageError(f"--samples-per-scene must be at least 1, got {args.samples_per_scene}")
    start = time.perf_counter()
    dataroot = synthesize(args.out, scenes=args.scenes, samples_per_scene=args.samples_per_scene,
                          with_images=args.with_images, with_lidar=args.with_lidar, seed=args.seed,
                          version=args.version, with_can_bus=args.can_bus,
                          profile=args.profile,
                          on_progress=bars(not args.quiet))
    files = [kind for kind, on in (("images", args.with_images), ("lidar/radar", args.with_lidar)) if on]
    print(f"wrote {dataroot / args.version}: {args.scenes} scenes x {args.samples_per_scene} samples"
          f"{' with ' + ' and '.join(files) if files else ' (tables only)'} in {time.perf_counter() - start:.1f} s",
          file=sys.stderr if args.quiet else sys.stdout)
    return 0
