"""`nuparquet convert DATAROOT --version V --out OUT`."""

from __future__ import annotations

import sys
import time


def register(sub) -> None:
    p = sub.add_parser(
        "convert",
        help="convert a nuScenes-layout dataroot to typed, denormalised Parquet",
        description="Parse, validate and convert DATAROOT/VERSION/*.json into OUT: tables/<name> (every source "
        "table, typed, lossless), frames/, annotations/, scenes/, instances/ (denormalised) and manifest.json. "
        "Output is written to a hidden sibling and renamed into place only when complete. Sensor files "
        "are not needed (partial downloads are fine). Exit 1 if the input has problems (all are listed).",
    )
    p.add_argument("dataroot", help="dataset root holding the version folder (e.g. /data/nuscenes)")
    p.add_argument("--version", required=True, help="version folder name, e.g. v1.0-mini or v1.0-trainval")
    p.add_argument("--out", required=True, help="output directory (must not exist unless --overwrite)")
    p.add_argument("--overwrite", action="store_true", help="replace OUT if it exists (only once the new one is complete)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.convert import convert
    start = time.perf_counter()
    manifest = convert(args.dataroot, args.version, args.out, overwrite=args.overwrite, progress=not args.quiet)
    rows = {name: d["rows"] for name, d in manifest["datasets"].items() if "/" not in name}
    summary = ", ".join(f"{n} {r:,}" for n, r in rows.items())
    print(f"converted {args.dataroot}/{args.version} -> {args.out} in {time.perf_counter() - start:.1f} s ({summary})",
          file=sys.stderr if args.quiet else sys.stdout)
    return 0
