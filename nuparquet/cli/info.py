"""`nuparquet info OUT`: what a converted directory holds (manifest, datasets, row counts, size on disk)."""

from __future__ import annotations

import json
import sys


def register(sub) -> None:
    p = sub.add_parser(
        "info",
        help="summarise a converted dataset: manifest, datasets, row counts, size on disk",
        description="Print the manifest of OUT (format version, source version and dataroot, creation time), its "
        "sensor channels (cameras front row | back row, lidars with the reference one, radars) and "
        "one line per dataset with its row count (read from the Parquet footers and checked against the "
        "manifest), number of files and size on disk. Exit 1 if OUT is not a nuparquet output or the row "
        "counts disagree with the manifest.",
    )
    p.add_argument("out", metavar="OUT", help="a directory written by `nuparquet convert` (or a URL polars can scan)")
    p.add_argument("--format", choices=("table", "csv", "json"), default="table",
                   help="table (default); csv: the dataset lines only; json: manifest summary and dataset lines")
    p.set_defaults(run=run)


def _size(n: int | None) -> str:
    if n is None:
        return "?"
    size = float(n)
    for unit in ("B", "KB", "MB", "GB"):
        if size < 1024 or unit == "GB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    return f"{n} B"


def run(args) -> int:
    import polars as pl

    from nuparquet.cli.output import print_frame, records
    from nuparquet.dataset import open_dataset

    ds = open_dataset(args.out)
    inventory = ds.inventory()
    mismatched = inventory.filter(pl.col("manifest_rows").is_not_null() & (pl.col("rows") != pl.col("manifest_rows")))
    total = inventory["bytes"].sum() if inventory["bytes"].null_count() == 0 else None
    m = ds.manifest
    if args.format == "json":
        print(json.dumps({
            "root": ds.root, "format": m["format"], "format_version": m["format_version"],
            "nuparquet_version": m.get("nuparquet_version"), "created_utc": m.get("created_utc"),
            "source": {"version": ds.version, "dataroot": ds.dataroot,
                       "files": len(m.get("source", {}).get("files", {}))},
            "channels": ds.channels, "total_bytes": total, "datasets": records(inventory),
        }, indent=1))
    elif args.format == "csv":
        print_frame(inventory, "csv")
    else:
        print(f"nuparquet dataset {ds.root}")
        print(f"  format:    {m['format']} {m['format_version']}, written by nuparquet {m.get('nuparquet_version', '?')} "
              f"at {m.get('created_utc', '?')}")
        print(f"  source:    {ds.version} at {ds.dataroot}")
        print(f"  datasets:  {len(ds.datasets)}, {_size(total)} on disk")
        channels = ds.channels
        print(f"  cameras:   {' | '.join(' '.join(row) for row in channels['camera_layout']) or '(none)'}")
        print(f"  lidars:    {' '.join(channels['lidars']) or '(none)'} (reference: {channels['reference_lidar']})")
        print(f"  radars:    {' '.join(channels['radars']) or '(none)'}")
        if "scenes" in ds.datasets:  # the names `render --scene` and `stats --scene` take
            names = ds.scan("scenes").select("name").collect()["name"].to_list()
            shown_names = " ".join(names[:20]) + (f" ... ({len(names)} in all)" if len(names) > 20 else "")
            print(f"  scenes:    {shown_names or '(none)'}")
        print()
        shown = inventory.with_columns(pl.col("bytes").map_elements(_size, return_dtype=pl.String).alias("size"))
        print_frame(shown.drop("manifest_rows", "bytes"), "table")
    for row in mismatched.iter_rows(named=True):
        print(f"warning: {row['dataset']} has {row['rows']:,} rows but the manifest says {row['manifest_rows']:,}",
              file=sys.stderr)
    return 1 if mismatched.height else 0
