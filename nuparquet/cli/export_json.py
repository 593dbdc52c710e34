"""`nuparquet export-json OUT --out DIR`: the source tables back as nuScenes JSON."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser(
        "export-json",
        help="write the tables of a conversion back as nuScenes JSON (lossless round trip)",
        description="Write OUT/tables/* as DIR/<table>.json. Parsing them gives records equal field for field "
        "to the converted input: same key order, bit-identical floats, [] for empty intrinsics.",
    )
    p.add_argument("dataset", help="a directory written by `nuparquet convert`")
    p.add_argument("--out", required=True, help="directory for the JSON files (must not exist unless --overwrite)")
    p.add_argument("--overwrite", action="store_true", help="replace DIR if it exists")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.export import export_json
    paths = export_json(args.dataset, args.out, overwrite=args.overwrite)
    print(f"wrote {len(paths)} tables to {args.out}")
    return 0
