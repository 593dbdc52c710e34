"""Row 1's floor: DuckDB copying the same JSON tables to Parquet with no typing checks or joins.

    .venv/bin/python benchmarks/duckdb_floor.py DATAROOT VERSION [--threads N]

For each `<table>.json` of DATAROOT/VERSION, one `COPY (SELECT * FROM read_json(...)) TO ... (FORMAT parquet)`,
in one process, into a temporary folder deleted afterwards; prints one JSON line (total seconds, per table).
The parent measures the process (wall time and peak RSS) with the harness, as it does `nuparquet convert`.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataroot")
    parser.add_argument("version")
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    args = parser.parse_args()
    import duckdb

    tables = sorted((Path(args.dataroot) / args.version).glob("*.json"))
    out = Path(tempfile.mkdtemp(prefix="duckdb-floor-"))
    per_table = {}
    start = time.perf_counter()
    try:
        con = duckdb.connect()
        con.execute(f"SET threads = {int(args.threads)}")
        for table in tables:
            t = time.perf_counter()
            con.execute(f"COPY (SELECT * FROM read_json('{table}', format='array', maximum_object_size=1073741824)) "
                        f"TO '{out / (table.stem + '.parquet')}' (FORMAT parquet)")
            per_table[table.stem] = round(time.perf_counter() - t, 3)
    finally:
        shutil.rmtree(out, ignore_errors=True)
    print(json.dumps({"seconds": time.perf_counter() - start, "tables": per_table}))


if __name__ == "__main__":
    main()
