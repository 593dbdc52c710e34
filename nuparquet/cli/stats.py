"""`nuparquet stats OUT`: the canned queries of `nuparquet.queries` as terminal tables, CSV or JSON, and charts."""

from __future__ import annotations

import json
import sys
from typing import TYPE_CHECKING

from nuparquet import queries
from nuparquet.cli.arguments import FORMATS
from nuparquet.errors import UsageError
from nuparquet.queries.sections import BY_NAME, default_sections

if TYPE_CHECKING:
    import polars as pl



def register(sub) -> None:
    p = sub.add_parser(
        "stats",
        help="print dataset statistics (categories, attributes, visibility, points, distances, tracks, ego speed, "
        "frame rates); optionally write PNG charts",
        description="Run the canned queries of nuparquet.queries over OUT and print one section each: "
        f"{', '.join(queries.SECTIONS)} (and on request with --only: {', '.join(queries.EXTRA_SECTIONS)}). "
        "Table output is for reading; csv prints each section as '# <section>' followed by its CSV (a single "
        "section, --only X, as plain CSV); json "
        "prints one object {section: [rows]}. With --plots DIR the charts class_distribution.png, "
        "distance_histogram.png, lidar_points_per_box.png and ego_speed.png are written to DIR, and with the CAN bus "
        "converted can_speed.png (CAN vs ego-pose speed) and steering.png for the scene (default: the first).",
        epilog="examples: nuparquet stats OUT;  nuparquet stats OUT --scene scene-0061 --plots plots/;  "
        "nuparquet stats OUT --only class_distribution --format csv",
    )
    p.add_argument("out", metavar="OUT", help="a directory written by `nuparquet convert` (or a URL polars can scan)")
    p.add_argument("--scene", action="append", metavar="NAME",
                   help="only this scene (repeat for several); reads only the row groups holding it")
    p.add_argument("--format", choices=FORMATS, default="table", help="table (default), csv or json")
    p.add_argument("--only", action="append", metavar="SECTION", choices=list(BY_NAME),
                   help="print only this section (repeatable); one of: "
                   f"{', '.join(BY_NAME)}")
    p.add_argument("--plots", metavar="DIR", help="also write PNG charts into DIR")
    p.add_argument("--bin-width", type=float, default=10.0, metavar="M",
                   help="distance histogram bin width in metres (default 10)")
    p.add_argument("--max-rows", type=int, default=60, metavar="N",
                   help="rows per section in table format (default 60; csv and json print every row)")
    p.set_defaults(run=run)


def _mean_std(df: pl.DataFrame, name: str) -> pl.Series:
    """``mean±std`` text with two decimals, as list_categories prints it."""
    import polars as pl

    return pl.Series(name, [f"{m:.2f}\u00b1{s:.2f}" for m, s in zip(df[f"{name}_mean"], df[f"{name}_std"])],
                     dtype=pl.String)


def display(section: str, df: pl.DataFrame) -> pl.DataFrame:
    """A narrower, readable version of one section for the terminal (csv/json print the full columns)."""
    import polars as pl

    if df.is_empty():
        return df
    if section.startswith("class_distribution"):
        keys = [c for c in ("scene_name", "category_name") if c in df.columns]
        return df.select(*keys, pl.col("num_annotations").alias("annotations"),
                         pl.col("num_instances").alias("instances"),
                         *(_mean_std(df, n) for n in ("width", "length", "height", "lw_aspect")))
    if section == "scenes":
        return df.select("name", "start_utc", "duration_s", "log_location", "nbr_samples",
                         pl.col("num_annotations").alias("annotations"),
                         pl.col("num_annotations_list_scenes").alias("anns_list_scenes"),
                         pl.col("num_instances").alias("instances"), "ego_distance_m")
    if section == "visibility":
        return (df.with_columns(pl.format("v{}", pl.col("visibility_level").cast(pl.String).fill_null("?"))
                                .alias("level"))
                .pivot("level", index="category_name", values="count", sort_columns=True)
                .fill_null(0))
    if section == "distance_histogram":
        wide = (df.with_columns(pl.format("{}-{}", pl.col("bin_start_m").cast(pl.Int64),
                                          pl.col("bin_end_m").cast(pl.Int64)).alias("bin"))
                .sort("bin_start_m")
                .pivot("bin", index="category_name", values="count")
                .fill_null(0))
        return wide.sort("category_name")
    if section == "points_per_box":
        return df.select(
            "category_name", pl.col("num_boxes").alias("boxes"),
            *(pl.col(f"{s}_{q}").alias(f"{s} {q}") for s in ("lidar", "radar")
              for q in ("mean", "p05", "p50", "p95", "max")),
            *(pl.Series(f"{s} zero", [f"{v:.1%}" for v in df[f"{s}_zero_share"]], dtype=pl.String)
              for s in ("lidar", "radar")),
        ).select("category_name", "boxes", *(f"lidar {q}" for q in ("mean", "p05", "p50", "p95", "max")),
                 "lidar zero", *(f"radar {q}" for q in ("mean", "p05", "p50", "p95", "max")), "radar zero")
    return df


def run(args) -> int:
    import math

    import polars as pl

    from nuparquet.cli.output import print_frame, records
    from nuparquet.dataset import open_dataset

    if not (math.isfinite(args.bin_width) and args.bin_width > 0):
        raise UsageError(f"--bin-width must be a positive number of metres, got {args.bin_width}")
    if args.max_rows < 1:
        raise UsageError(f"--max-rows must be at least 1, got {args.max_rows}")
    ds = open_dataset(args.out)
    scene = None
    if args.scene:
        ds.check_scenes(args.scene)
        scene = args.scene[0] if len(args.scene) == 1 else args.scene
    sections = list(dict.fromkeys(args.only or default_sections(ds)))
    wanted = sections + [s for s in ("class_distribution", "distance_histogram", "points_per_box", "ego_motion")
                         if args.plots and s not in sections]
    lazy = queries.summary(ds, scene=scene, sections=wanted, bin_width_m=args.bin_width)
    results = dict(zip(lazy, pl.collect_all(list(lazy.values()))))

    if args.format == "json":
        print(json.dumps({name: records(results[name]) for name in sections}, indent=1))
    else:
        if args.format == "table":
            where = f", scene {', '.join(args.scene)}" if args.scene else ""
            print(f"nuparquet stats: {ds.root} ({ds.version}{where})")
        for name in sections:
            if args.format == "csv":
                if len(sections) > 1:
                    print(f"# {name}")
                print_frame(results[name], "csv")
                if len(sections) > 1:
                    print()
            else:
                print_frame(display(name, results[name]), "table", title=f"== {BY_NAME[name].title}",
                            max_rows=args.max_rows)
    if args.plots:
        from nuparquet.rendering.pictures.charts import write_plots  # matplotlib only when asked for

        paths = write_plots(ds, args.plots, scene=scene, results=results)
        stream = sys.stdout if args.format == "table" else sys.stderr
        print(f"\nwrote {len(paths)} charts: {', '.join(str(p) for p in paths)}", file=stream)
    return 0
