"""Row 1m's floor: what the map expansion's conversion cannot do without, measured bare.

    .venv/bin/python benchmarks/map_floor.py DATAROOT

For each `maps/expansion/<location>.json`, in one process: a bare DuckDB read of the file into Arrow (the layers'
lists of structs, no checks: `SELECT * FROM read_json(...)`), then shapely's vectorised geometry construction of
every polygon (exterior ring and holes from node tokens) and every line, with token lookups through numpy
(`searchsorted` over the sorted node tokens). Prints one JSON line: total seconds and per map. The parent measures
the process (wall time and peak RSS) with the harness, as it does `nuparquet convert`.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path


def geometry(table) -> tuple[int, int]:
    """Every polygon and line of one map (Arrow table of one row) as shapely geometry: (polygons, lines)."""
    import numpy as np
    import pyarrow.compute as pc
    import shapely

    nodes = table.column("node")[0].values  # struct<token, x, y>
    tokens = nodes.field("token").to_numpy(zero_copy_only=False).astype(str)
    order = np.argsort(tokens)
    sorted_tokens = tokens[order]
    xy = np.column_stack([nodes.field("x").to_numpy(), nodes.field("y").to_numpy()])

    def points(token_lists):
        flat = pc.list_flatten(token_lists).to_numpy(zero_copy_only=False).astype(str)
        index = order[np.searchsorted(sorted_tokens, flat)]
        lengths = pc.list_value_length(token_lists).to_numpy()
        return xy[index], np.repeat(np.arange(len(lengths)), lengths)

    polygons = table.column("polygon")[0].values
    coords, ring_of = points(polygons.field("exterior_node_tokens"))
    rings = shapely.linearrings(coords, indices=ring_of)
    holes = polygons.field("holes")
    hole_rings = pc.list_flatten(holes)
    hole_coords, hole_of = points(hole_rings.field("node_tokens"))
    hole_geoms = shapely.linearrings(hole_coords, indices=hole_of) if len(hole_coords) else np.empty(0, object)
    hole_owner = np.repeat(np.arange(len(holes)), pc.list_value_length(holes).to_numpy())
    if len(hole_geoms):  # each polygon's rings together, its shell first
        owner = np.concatenate([np.arange(len(rings)), hole_owner])
        order_rings = np.argsort(owner, kind="stable")
        shapes = shapely.polygons(np.concatenate([rings, hole_geoms])[order_rings], indices=owner[order_rings])
    else:
        shapes = shapely.polygons(rings)
    lines = table.column("line")[0].values
    line_coords, line_of = points(lines.field("node_tokens"))
    line_geoms = shapely.linestrings(line_coords, indices=line_of)
    return len(shapes), len(line_geoms)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataroot")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    import duckdb

    per_map = {}
    start = time.perf_counter()
    con = duckdb.connect()
    con.execute(f"SET threads = {int(args.threads)}")
    for path in sorted((Path(args.dataroot) / "maps" / "expansion").glob("*.json")):
        t = time.perf_counter()
        table = con.sql(f"SELECT * FROM read_json('{path}', maximum_object_size=2147483647)").to_arrow_table()
        read_s = time.perf_counter() - t
        n_polygons, n_lines = geometry(table)
        per_map[path.stem] = {"read_s": round(read_s, 3), "total_s": round(time.perf_counter() - t, 3),
                              "polygons": n_polygons, "lines": n_lines}
    print(json.dumps({"seconds": time.perf_counter() - start, "maps": per_map}))


if __name__ == "__main__":
    main()
