"""`nuparquet index OUT --out DIR`: mmdetection3d's nuScenes info files (and DIR/infos/ Parquet) from a converted
directory, without the devkit. Flags come from `nuparquet.index.options.IndexOptions`."""

from __future__ import annotations

from nuparquet.cli.arguments import add_options, options_from
from nuparquet.cli.progress import bars
from nuparquet.index.options import IndexOptions


def register(sub) -> None:
    p = sub.add_parser(
        "index",
        help="write mmdetection3d training infos (nuscenes_infos_<split>.pkl) and DIR/infos/ Parquet",
        description="Write the info pickles mmdetection3d's `create_data.py nuscenes` writes (v1, or v2 after "
        "update_infos_to_v2; or the BEVFormer variant; or mmdetection3d 0.17's infos and mono3d COCO file), equal "
        "to its output for the same dataroot, plus DIR/infos/<split>.parquet (one row per sample, nested "
        "columns). Everything comes from the converted tables; no sensor file is opened. Exit 1 when OUT lacks a "
        "dataset the index needs.",
    )
    p.add_argument("dataset", metavar="OUT", help="a directory written by `nuparquet convert`")
    p.add_argument("--out", metavar="DIR", required=True,
                   help="output directory for the info files and infos/ (created; written atomically)")
    add_options(p, IndexOptions)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.index.build import build_index

    written = build_index(args.dataset, args.out, options_from(args, IndexOptions), on_progress=bars(not args.quiet))
    for name, path in written.items():
        print(f"{name}: {path}")
    return 0
