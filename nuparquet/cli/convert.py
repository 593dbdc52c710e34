"""`nuparquet convert DATAROOT --version V --out OUT`."""

from __future__ import annotations

import sys
import time

from nuparquet.cli.arguments import add_options, options_from
from nuparquet.conversion.options import ConvertOptions
from nuparquet.engine.options import EngineOptions


def register(sub) -> None:
    p = sub.add_parser(
        "convert",
        help="convert a nuScenes-layout dataroot to typed, denormalised Parquet",
        description="Parse, validate and convert DATAROOT/VERSION/*.json into OUT: tables/<name> (every source "
        "table, typed, lossless), frames/, annotations/, scenes/, instances/ (denormalised) and manifest.json "
        "(which also lists the datasets skipped and why, and the sensor channels). "
        "Output is written to a hidden sibling and renamed into place only when complete. Sensor files "
        "are not needed (partial downloads are fine) unless --sensors asks for the point clouds: then "
        "lidar_points/ and radar_points/ (one row per point, with lidarseg/panoptic labels when present; see "
        "docs/points.md) are converted scene by scene on --workers processes, or --embed asks for the files "
        "themselves: sensor_files/camera/, sensor_files/lidar/, sensor_files/radar/ (byte for byte, one part per "
        "scene), so the output alone serves images and points without a dataroot (e.g. from object storage). "
        "Exit 1 if the input has problems (all are listed).",
        epilog="example: nuparquet convert /data/nuscenes --version v1.0-mini --out nusc-mini --sensors lidar,radar",
    )
    p.add_argument("dataroot", help="dataset root holding the version folder (e.g. /data/nuscenes)")
    p.add_argument("--version", required=True, help="version folder name, e.g. v1.0-mini or v1.0-trainval")
    p.add_argument("--out", required=True, help="output directory (must not exist unless --overwrite)")
    add_options(p, ConvertOptions)
    add_options(p, EngineOptions, skip=("keep_going", "resume"), aliases={"workers": ("--jobs",)})
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.cli.progress import bars
    from nuparquet.conversion import convert

    start = time.perf_counter()
    manifest = convert(args.dataroot, args.version, args.out, options_from(args, ConvertOptions),
                       engine=options_from(args, EngineOptions), on_progress=bars(not args.quiet))
    for warning in manifest.get("warnings", [])[:20]:
        print(warning, file=sys.stderr)
    if len(manifest.get("warnings", [])) > 20:
        print(f"... and {len(manifest['warnings']) - 20} more warnings (manifest.json lists them)", file=sys.stderr)
    rows = {name: d["rows"] for name, d in manifest["datasets"].items() if not name.startswith("tables/")}
    summary = ", ".join(f"{n} {r:,}" for n, r in rows.items())
    print(f"converted {args.dataroot}/{args.version} -> {args.out} in {time.perf_counter() - start:.1f} s ({summary})",
          file=sys.stderr if args.quiet else sys.stdout)
    return 0
