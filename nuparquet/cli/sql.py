"""`nuparquet sql OUT "SELECT …"`: polars SQL over every dataset of a converted directory."""

from __future__ import annotations

from nuparquet.cli.arguments import FORMATS


def register(sub) -> None:
    p = sub.add_parser(
        "sql",
        help="run a polars SQL query over a converted dataset",
        description="Run one SQL query (polars SQL dialect) over the datasets of OUT and print the result. "
        "Tables: frames, annotations, scenes, instances, every other converted dataset by its name, and every "
        "source table as sample, scene, sample_annotation, … (also \"tables/sample\" and tables_sample). A name "
        "with a slash must be double-quoted: SELECT * FROM \"map/lane\", FROM \"can_bus/pose\", "
        "FROM \"tables/sample\" (single quotes would make it a string). "
        "Only the columns and row groups the query needs are read. Exit 1 for bad SQL or unknown "
        "tables or columns (the message says what is wrong).",
        epilog="example: nuparquet sql OUT \"SELECT category_name, COUNT(*) AS n FROM annotations "
        "GROUP BY category_name ORDER BY n DESC\"",
    )
    p.add_argument("out", metavar="OUT", help="a directory written by `nuparquet convert` (or a URL polars can scan)")
    p.add_argument("query", help="the SQL query (quote it for the shell)")
    p.add_argument("--format", choices=FORMATS, default="table",
                   help="table (readable, default), csv (header + rows) or json (a list of row objects)")
    p.add_argument("--max-rows", type=int, default=100, metavar="N",
                   help="rows shown in table format (default 100; csv and json print every row)")
    p.add_argument("--allow-file-access", action="store_true",
                   help="let the query call polars' file-reading table functions (read_csv, read_parquet, ...); "
                   "by default it reads this dataset only")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.cli.output import print_frame
    from nuparquet.dataset import open_dataset

    result = open_dataset(args.out).sql(args.query, allow_file_access=args.allow_file_access)
    print_frame(result, args.format, max_rows=args.max_rows if args.format == "table" else None)
    if args.format == "table":
        print(f"({result.height:,} row{'s' if result.height != 1 else ''})")
    return 0
