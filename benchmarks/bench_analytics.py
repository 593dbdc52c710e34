"""Row 6: `nuparquet stats` and one `nuparquet sql` query on the trainval-scale conversion vs polars directly on
the same Parquet files (a sanity check of the CLI's overhead: report only).

    .venv/bin/python benchmarks/bench_analytics.py [--repeats 3]

A fresh process per repeat, whole-process wall time and peak RSS:
- `nuparquet stats OUT` (every default section, table output) vs a process that builds the same lazy
  queries (`nuparquet.queries.summary`) over plain `pl.scan_parquet(OUT/<dataset>/*.parquet)` scans and
  collects them with one `pl.collect_all`: the same plans without the CLI, the manifest or the printing.
- `nuparquet sql OUT "<SQL>" --format csv` vs the same aggregation written in polars
  (`pl.scan_parquet(...).group_by(...).agg(...)`), printed as CSV; both outputs are checked equal.
"""

from __future__ import annotations

import argparse
import io
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

SQL = ("SELECT category_name, COUNT(*) AS n, AVG(num_lidar_pts) AS mean_lidar_pts FROM annotations "
       "GROUP BY category_name ORDER BY n DESC, category_name")


class _PlainScans:
    """Just enough of a Dataset for nuparquet.queries: `scan(name)` = pl.scan_parquet of its files."""

    def __init__(self, out: str):
        self.out = out

    def scan(self, name: str):
        import polars as pl

        return pl.scan_parquet(f"{self.out}/{name}/*.parquet")


def polars_stats_child(out: str) -> None:
    start = time.perf_counter()
    import polars as pl

    from nuparquet import queries

    lazy = queries.summary(_PlainScans(out), sections=queries.SECTIONS)
    results = pl.collect_all(list(lazy.values()))
    rows = {name: result.height for name, result in zip(lazy, results)}
    print(json.dumps({"in_process_s": time.perf_counter() - start, "rows": rows}))


def polars_sql_child(out: str) -> None:
    import polars as pl

    result = (
        pl.scan_parquet(f"{out}/annotations/*.parquet")
        .group_by("category_name")
        .agg(pl.len().alias("n"), pl.col("num_lidar_pts").mean().alias("mean_lidar_pts"))
        .sort(["n", "category_name"], descending=[True, False])
        .collect()
    )
    sys.stdout.write(result.write_csv())


def _same_csv(a: str, b: str) -> bool:
    import polars as pl

    left, right = pl.read_csv(io.StringIO(a)), pl.read_csv(io.StringIO(b))
    if left.columns != right.columns or left.height != right.height:
        return False
    return (left["category_name"].to_list() == right["category_name"].to_list()
            and left["n"].to_list() == right["n"].to_list()
            and ((left["mean_lidar_pts"] - right["mean_lidar_pts"]).abs().max() or 0.0) < 1e-9)


def run(repeats: int = 3) -> dict:
    import bench_data as datasets
    from harness import Row, log, megabytes, python_child, repeat, seconds, summarize, times

    out = datasets.trainval_out()
    log("row 6: nuparquet stats and sql vs polars")
    from nuparquet import queries

    # the core sections (what the polars reference runs); the map sections, default when map/ was converted, are
    # timed on their own (row 6c: point-in-polygon for every annotation centre)
    stats_cmd = [*datasets.NUPARQUET, "stats", str(out), *(a for s in queries.SECTIONS for a in ("--only", s))]
    map_cmd = [*datasets.NUPARQUET, "stats", str(out), "--only", "map_surfaces", "--only", "ego_on_map"]
    stats_ref_cmd = python_child(__file__, "--polars-stats", out)
    sql_cmd = [*datasets.NUPARQUET, "sql", str(out), SQL, "--format", "csv"]
    sql_ref_cmd = python_child(__file__, "--polars-sql", out)
    stats = summarize(repeat(stats_cmd, repeats, label="nuparquet stats"))
    map_stats = summarize(repeat(map_cmd, repeats, label="nuparquet stats, map sections"))
    stats_ref = summarize(repeat(stats_ref_cmd, repeats, label="polars stats queries"), in_process_s="in_process_s")
    sql_runs = repeat(sql_cmd, repeats, label="nuparquet sql")
    sql_ref_runs = repeat(sql_ref_cmd, repeats, label="polars sql equivalent")
    sql, sql_ref = summarize(sql_runs), summarize(sql_ref_runs)
    same = _same_csv(sql_runs[0].stdout, sql_ref_runs[0].stdout)
    rows = [
        Row(
            id="6a",
            benchmark=f"`nuparquet stats` on trainval scale ({len(queries.SECTIONS)} core sections)",
            ours=f"{seconds(stats['wall_s'])}, {megabytes(stats['max_rss_mb'])} peak",
            reference=f"polars, same lazy queries: {seconds(stats_ref['wall_s'])}, "
            f"{megabytes(stats_ref['max_rss_mb'])} peak",
            ratio=f"{times(stats_ref['wall_s'] / stats['wall_s'])} of polars' speed",
            target="report",
            met=None,
        ),
        Row(
            id="6b",
            benchmark="`nuparquet sql` on trainval scale: annotations and mean lidar points per category",
            ours=f"{seconds(sql['wall_s'])}, {megabytes(sql['max_rss_mb'])} peak",
            reference=f"polars group_by: {seconds(sql_ref['wall_s'])}, {megabytes(sql_ref['max_rss_mb'])} peak",
            ratio=f"{times(sql_ref['wall_s'] / sql['wall_s'])} of polars' speed",
            target="report",
            met=None,
            note=f"row 6 check: nuparquet sql output equal to polars': {same}",
        ),
        Row(
            id="6c",
            benchmark="`nuparquet stats --only map_surfaces --only ego_on_map` on trainval scale (every annotation "
            "centre and reference keyframe pose on 9 polygon layers of the synthetic maps)",
            ours=f"{seconds(map_stats['wall_s'])}, {megabytes(map_stats['max_rss_mb'])} peak",
            reference="—", ratio="—", target="report", met=None,
        ),
    ]
    return {"name": "analytics", "sql": SQL, "map_stats": map_stats,
            "commands": {"stats": " ".join(stats_cmd), "map_stats": " ".join(map_cmd), "stats_reference": " ".join(map(str, stats_ref_cmd)),
                         "sql": " ".join(sql_cmd[:-3]) + f' "{SQL}" --format csv',
                         "sql_reference": " ".join(map(str, sql_ref_cmd))},
            "stats": stats, "stats_reference": stats_ref, "sql_result": sql, "sql_reference": sql_ref,
            "sql_same_output": same, "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--polars-stats", metavar="OUT", help=argparse.SUPPRESS)
    parser.add_argument("--polars-sql", metavar="OUT", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.polars_stats:
        polars_stats_child(args.polars_stats)
        return
    if args.polars_sql:
        polars_sql_child(args.polars_sql)
        return
    from harness import report_alone

    report_alone(run(args.repeats))


if __name__ == "__main__":
    main()
