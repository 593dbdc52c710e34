"""`nuparquet export-coco DATASET --out FILE.json`: a nuImages conversion's 2D annotations as a COCO file.
The flags come from `nuparquet.export.coco_options.CocoOptions`."""

from __future__ import annotations

from nuparquet.cli.arguments import add_options, options_from
from nuparquet.export.coco_options import CocoOptions


def register(sub) -> None:
    p = sub.add_parser(
        "export-coco",
        help="write a nuImages conversion's boxes and masks as a COCO instances file (mmdetection's format)",
        description="Write the object annotations of a nuImages conversion as one COCO instances JSON file: every "
        "keyframe image, each object with a mask as bbox [x, y, w, h], area, iscrowd 0 and its mask as COCO "
        "compressed RLE (pycocotools decodes it to the devkit's mask), and the categories. The default is the file "
        "mmdetection3d's nuimage_converter.py writes, byte for byte.",
        epilog="example: nuparquet export-coco nuim-out --out annotations/nuimages_v1.0-mini.json",
    )
    p.add_argument("dataset", help="a directory written by `nuparquet convert` of a nuImages dataroot")
    p.add_argument("--out", required=True, help="the JSON file to write")
    add_options(p, CocoOptions)
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.export.coco import export_coco

    path = export_coco(args.dataset, args.out, options_from(args, CocoOptions))
    print(f"wrote {path}")
    return 0
