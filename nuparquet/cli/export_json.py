"""`nuparquet export-json OUT --out DIR`: every JSON file a conversion read, written back under DIR as a dataroot."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser(
        "export-json",
        help="write the tables of a conversion back as nuScenes JSON (lossless round trip)",
        description="Write every JSON file the conversion read back under DIR, at its path relative to the "
        "dataroot (the tables as DIR/<version>/<table>.json). Parsing them gives records equal field for field "
        "to the converted input: same key order, bit-identical floats, [] for empty intrinsics.",
    )
    p.add_argument("dataset", help="a directory written by `nuparquet convert`")
    p.add_argument("--out", required=True, help="directory for the JSON files (must not exist unless --overwrite)")
    p.add_argument("--overwrite", action="store_true", help="replace DIR if it exists")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.cli.progress import bars
    from nuparquet.export.json_files import export_json

    paths = export_json(args.dataset, args.out, overwrite=args.overwrite, on_progress=bars(not args.quiet))
    print(f"wrote {len(paths)} files to {args.out}")
    return 0
