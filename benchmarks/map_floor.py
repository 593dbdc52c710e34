"""Row 1m's floor: the map expansion read by DuckDB and its geometry built by shapely's vectorised constructors, no
checks, nothing kept for an exact round trip; and, for the same files, the map part of `nuparquet convert`.

    .venv/bin/python benchmarks/map_floor.py DATAROOT [--threads 2]         # the floor, one process
    .venv/bin/python benchmarks/map_floor.py DATAROOT --ours                # the map builder + its Parquet writes
    .venv/bin/python benchmarks/map_floor.py [--repeats 3]                  # both on the trainval-scale maps: row 1m'

The floor, per `maps/expansion/<location>.json`: one `read_json` of the file into a DuckDB table with the v1.3 layout
given (`COLUMNS`: one parse, no inference pass; the lane-keyed objects as MAPs), the node rows and every
node-token list unnested and joined to node row numbers in SQL, then `shapely.points` of the nodes,
`shapely.linestrings` of the lines, `shapely.linearrings` + `shapely.polygons` of the polygons (holes included),
each layer's geometry gathered from its polygon or line (drivable areas as `shapely.multipolygons`), and every
geometry to WKB. Ours: `conversion.builders.map_expansion.build` (read, check, type every field losslessly,
geometry, lane centrelines) and `write_parquet` of each dataset it returns, what `nuparquet convert` runs for the
map. Both print one JSON line; the parent (`run`) measures the processes with the harness.
Target (issue 26): ours ≤ 2x the floor.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

TARGET_RATIO = 2.0
POLYGON_LAYERS = ("drivable_area", "road_segment", "road_block", "lane", "ped_crossing", "walkway", "stop_line",
                  "carpark_area", "lane_connector")
LINE_LAYERS = ("road_divider", "lane_divider", "traffic_light")
# The map expansion v1.3 layout, given to DuckDB so it parses each file once (no inference pass); nested
# fields nobody unnests stay JSON, the lane-keyed objects become MAPs.
_S = "VARCHAR"
COLUMNS = {
    "version": _S,
    "polygon": f"STRUCT(token {_S}, exterior_node_tokens {_S}[], holes STRUCT(node_tokens {_S}[])[])[]",
    "line": f"STRUCT(token {_S}, node_tokens {_S}[])[]",
    "node": f"STRUCT(token {_S}, x DOUBLE, y DOUBLE)[]",
    "drivable_area": f"STRUCT(token {_S}, polygon_tokens {_S}[])[]",
    "road_segment": f"STRUCT(token {_S}, polygon_token {_S}, is_intersection BOOLEAN, drivable_area_token {_S})[]",
    "road_block": f"STRUCT(token {_S}, polygon_token {_S}, from_edge_line_token {_S}, to_edge_line_token {_S}, "
                  f"road_segment_token {_S})[]",
    "lane": f"STRUCT(token {_S}, polygon_token {_S}, lane_type {_S}, from_edge_line_token {_S}, to_edge_line_token "
            f"{_S}, left_lane_divider_segments JSON, right_lane_divider_segments JSON)[]",
    "ped_crossing": f"STRUCT(token {_S}, polygon_token {_S}, road_segment_token {_S})[]",
    "walkway": f"STRUCT(token {_S}, polygon_token {_S})[]",
    "stop_line": f"STRUCT(token {_S}, polygon_token {_S}, stop_line_type {_S}, ped_crossing_tokens {_S}[], "
                 f"traffic_light_tokens {_S}[], road_block_token {_S})[]",
    "carpark_area": f"STRUCT(token {_S}, polygon_token {_S}, orientation DOUBLE, road_block_token {_S})[]",
    "road_divider": f"STRUCT(token {_S}, line_token {_S}, road_segment_token {_S})[]",
    "lane_divider": f"STRUCT(token {_S}, line_token {_S}, lane_divider_segments JSON)[]",
    "traffic_light": f"STRUCT(token {_S}, line_token {_S}, traffic_light_type {_S}, from_road_block_token {_S}, "
                     "items JSON, pose JSON)[]",
    "canvas_edge": "DOUBLE[]",
    "connectivity": f"MAP({_S}, JSON)",
    "arcline_path_3": f"MAP({_S}, JSON)",
    "lane_connector": f"STRUCT(token {_S}, polygon_token {_S})[]",
}


def _floor_map(con, path: Path) -> dict:
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc
    import shapely

    times = {}
    t = time.perf_counter()
    columns = "{" + ", ".join(f"'{k}': '{v}'" for k, v in COLUMNS.items()) + "}"
    con.execute(f"CREATE OR REPLACE TEMP TABLE m AS SELECT * FROM read_json('{path}', format='unstructured', "
                f"columns={columns}, maximum_object_size=2147483647)")
    times["read_s"] = time.perf_counter() - t
    t = time.perf_counter()

    def layer(name: str, *fields: str) -> pa.Table:
        return con.sql(f"SELECT {', '.join(f'r.{f} AS {f}' for f in fields)} FROM (SELECT unnest({name}) AS r "
                       "FROM m)").to_arrow_table()

    def as_table(result) -> pa.Table:
        return result.read_all() if hasattr(result, "read_all") else result

    nodes = as_table(layer("node", "token", "x", "y"))
    xy = np.c_[nodes["x"].to_numpy(), nodes["y"].to_numpy()]
    node_tokens = nodes["token"].combine_chunks()

    def node_rows(lists: pa.ChunkedArray) -> tuple[np.ndarray, np.ndarray]:
        """(L,) lengths and (K,) node rows of L node-token lists (hash lookups in Arrow)."""
        lists = lists.combine_chunks() if hasattr(lists, "combine_chunks") else lists
        rows = pc.index_in(pc.list_flatten(lists), value_set=node_tokens).to_numpy(zero_copy_only=False)
        return pc.list_value_length(lists).fill_null(0).to_numpy(zero_copy_only=False).astype(np.int64), rows

    geometry = {"node": shapely.points(xy)}
    lines_t = as_table(layer("line", "token", "node_tokens"))
    lengths, rows = node_rows(lines_t["node_tokens"])
    lines = np.full(len(lengths), None, dtype=object)
    ok = lengths >= 2
    keep = np.repeat(ok, lengths)
    lines[ok] = shapely.linestrings(xy[rows[keep]], indices=np.repeat(np.arange(ok.sum()), lengths[ok]))
    polygons_t = as_table(layer("polygon", "token", "exterior_node_tokens", "holes"))
    n_polygons = polygons_t.num_rows
    ext_len, ext_rows = node_rows(polygons_t["exterior_node_tokens"])
    holes = polygons_t["holes"].combine_chunks()
    holes_per_polygon = pc.list_value_length(holes).fill_null(0).to_numpy(zero_copy_only=False).astype(np.int64)
    hole_len, hole_rows = node_rows(pc.struct_field(pc.list_flatten(holes), "node_tokens"))
    # rings in order: each polygon's exterior, then its holes (empty holes dropped, as the devkit drops them)
    ring_polygon = np.r_[np.arange(n_polygons), np.repeat(np.arange(n_polygons), holes_per_polygon)]
    ring_len = np.r_[ext_len, hole_len]
    ring_start = np.r_[np.cumsum(ext_len) - ext_len, len(ext_rows) + np.cumsum(hole_len) - hole_len]
    all_rows = np.r_[ext_rows, hole_rows]
    order = np.lexsort((np.r_[np.zeros(n_polygons), np.ones(len(hole_len))], ring_polygon))
    order = order[ring_len[order] > 0]
    flat = all_rows[np.concatenate([np.arange(ring_start[i], ring_start[i] + ring_len[i]) for i in order])] \
        if len(order) else np.zeros(0, np.int64)
    rings = shapely.linearrings(xy[flat], indices=np.repeat(np.arange(len(order)), ring_len[order]))
    polygons = np.full(n_polygons, None, dtype=object)
    built, which = np.unique(ring_polygon[order], return_inverse=True)
    polygons[built] = shapely.polygons(rings, indices=which)
    geometry |= {"line": lines, "polygon": polygons}
    polygon_tokens = polygons_t["token"].combine_chunks()
    line_tokens = lines_t["token"].combine_chunks()
    for name in POLYGON_LAYERS + LINE_LAYERS:
        if name == "drivable_area":
            lists = as_table(layer(name, "polygon_tokens"))["polygon_tokens"].combine_chunks()
            parts = pc.index_in(pc.list_flatten(lists), value_set=polygon_tokens).to_numpy(zero_copy_only=False)
            counts = pc.list_value_length(lists).to_numpy(zero_copy_only=False).astype(np.int64)
            geometry[name] = shapely.multipolygons(polygons[parts], indices=np.repeat(np.arange(len(counts)), counts))
            continue
        key, tokens, source = (("polygon_token", polygon_tokens, polygons) if name in POLYGON_LAYERS
                               else ("line_token", line_tokens, lines))
        refs = as_table(layer(name, key))[key]
        geometry[name] = source[pc.index_in(refs, value_set=tokens).to_numpy(zero_copy_only=False)]
    times["geometry_s"] = time.perf_counter() - t
    t = time.perf_counter()
    wkb_bytes = sum(int(sum(map(len, shapely.to_wkb(g[~shapely.is_missing(g)])))) for g in geometry.values())
    times["wkb_s"] = time.perf_counter() - t
    times["records"] = {k: int(len(v)) for k, v in geometry.items()}
    times["wkb_bytes"] = wkb_bytes
    return times


def floor_child(dataroot: str, threads: int) -> None:
    import duckdb
    import pyarrow.compute  # noqa: F401 - imported before the clock, like the modules of the other side
    import shapely  # noqa: F401

    start = time.perf_counter()
    con = duckdb.connect()
    con.execute(f"SET threads = {int(threads)}")
    maps = {p.stem: _floor_map(con, p) for p in sorted((Path(dataroot) / "maps" / "expansion").glob("*.json"))}
    print(json.dumps({"seconds": time.perf_counter() - start, "maps": maps}))


def ours_child(dataroot: str) -> None:
    from nuparquet.conversion.builder import BuildContext
    from nuparquet.conversion.builders.map_expansion import build
    from nuparquet.conversion.options import ConvertOptions
    from nuparquet.conversion.write import write_parquet
    from nuparquet.engine.options import EngineOptions

    start = time.perf_counter()
    out = Path(tempfile.mkdtemp(prefix="map-ours-"))
    try:
        ctx = BuildContext(dataroot=Path(dataroot), version="", options=ConvertOptions(), engine=EngineOptions(),
                           tables={}, out=out)
        tables = build(ctx)
        built = time.perf_counter()
        written = sum(write_parquet(table, out / name, group_by="location") for name, table in tables.items())
    finally:
        shutil.rmtree(out, ignore_errors=True)
    end = time.perf_counter()
    print(json.dumps({"seconds": end - start, "build_s": built - start, "write_s": end - built,
                      "datasets": len(tables), "parquet_bytes": written}))


def run(repeats: int = 3) -> dict:
    import bench_data as datasets
    from harness import PYTHON, Row, log, megabytes, repeat, seconds, summarize

    root = datasets.trainval_root()
    map_bytes = sum(p.stat().st_size for p in (root / "maps" / "expansion").glob("*.json"))
    log(f"row 1m': the map conversion ({map_bytes / 1e9:.2f} GB of map JSON) vs DuckDB read + shapely geometry")
    floor_cmd = [PYTHON, __file__, str(root), "--threads", "2"]
    ours_cmd = [PYTHON, __file__, str(root), "--ours"]
    floor_runs, ours_runs = [], []
    for _ in range(repeats):  # interleaved: a busy moment hits both alike
        floor_runs += repeat(floor_cmd, 1, label="map floor (DuckDB + shapely)")
        ours_runs += repeat(ours_cmd, 1, label="map conversion (build + write)")
    floor = summarize(floor_runs, seconds="seconds")
    ours = summarize(ours_runs, seconds="seconds", build_s="build_s", write_s="write_s")
    ratio = ours["wall_s"] / floor["wall_s"]
    row = Row(id="1m'", benchmark=f"the map part of convert alone: {map_bytes / 1e9:.2f} GB of map JSON -> map/ "
              "GeoParquet (`map_expansion.build` + Parquet writes)",
              ours=f"{seconds(ours['wall_s'])} (build {seconds(ours['build_s'])}, write {seconds(ours['write_s'])}), "
              f"{megabytes(ours['max_rss_mb'])} peak",
              reference=f"DuckDB read_json + shapely vectorised geometry + WKB: {seconds(floor['wall_s'])}, "
              f"{megabytes(floor['max_rss_mb'])} peak", ratio=f"{ratio:.2f}x the floor's time",
              target=f"≤ {TARGET_RATIO:.0f}x", met=ratio <= TARGET_RATIO)
    return {"name": "map_convert", "nuparquet": ours, "floor": floor, "ratio": ratio, "map_json_bytes": map_bytes,
            "commands": {"ours": " ".join(map(str, ours_cmd)), "floor": " ".join(map(str, floor_cmd))},
            "rows": [row]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataroot", nargs="?", help="a dataroot holding maps/expansion/*.json (a child process)")
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    parser.add_argument("--ours", action="store_true", help="run the map conversion instead of the floor")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    if args.dataroot and args.ours:
        ours_child(args.dataroot)
    elif args.dataroot:
        floor_child(args.dataroot, args.threads)
    else:
        from harness import report_alone

        report_alone(run(args.repeats))


if __name__ == "__main__":
    main()
