"""`map/<layer>/` (GeoParquet 1.1, one row per record of every layer of every map, sorted by location),
`map/arcline_path_3/`, `map/connectivity/` and `map/lane_centerlines/`, from `maps/expansion/*.json`.

Record fields are typed by inference (`json_records`), so every map file comes back exactly (`export-json`,
kind "map_expansion"); `location` comes first, `geometry` (WKB) and `bbox` last on the geometric layers.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import shapely

from nuparquet.conversion.builder import BuildContext, Builder
from nuparquet.map.centerlines import discretize_lanes
from nuparquet.map.geo import geometry_columns, with_geo_metadata
from nuparquet.map.layers import DICT_LAYERS, LIST_LAYERS
from nuparquet.problems import Problem, ProblemsFound
from nuparquet.schemas import check_columns, schema_for
from nuparquet.sources import map_expansion as source
from nuparquet.sources.json_records import range_facts

CENTERLINE_RESOLUTION_M = 0.5  # the devkit's get_closest_lane resolution
FILE_KIND = "map_expansion"


def wanted(ctx: BuildContext) -> str | None:
    if getattr(ctx.options, "no_map", False):
        return "not requested (--no-map)"
    if not (ctx.dataroot / source.FOLDER).is_dir():
        return f"no {source.FOLDER}/ folder in the dataroot"
    if not source.discover(ctx.dataroot):
        return f"no map files in {source.FOLDER}/"
    return None


def build(ctx: BuildContext) -> dict[str, pa.Table]:
    maps, problems = [], []
    for relative in source.discover(ctx.dataroot):
        if ctx.reporter:
            ctx.reporter.note(f"map {relative.stem}")
        read, read_problems = source.read_map(ctx.dataroot, relative)
        problems += read_problems
        if read is not None:
            maps.append(read)
    if problems:
        raise ProblemsFound(problems)
    entries = [{"path": m.path, "kind": FILE_KIND, "dataset": "map", "location": m.location,
                "top_keys": list(m.data), "scalars": m.scalars, "layers": {}} for m in maps]
    extra = {"maps": {m.location: {"canvas_edge_m": m.data.get("canvas_edge"), "version": m.data.get("version"),
                                   "origin_lat_lon": source.ORIGIN_LAT_LON.get(m.location)} for m in maps},
             "units": "metres from the map's south-west corner (x east, y north)"}
    out: dict[str, pa.Table] = {}
    for layer in LIST_LAYERS:
        table, layer_problems = _layer_table(maps, layer, entries)
        problems += layer_problems
        if table is not None:
            geometries = np.concatenate([m.geometry[layer] for m in maps]) if maps else np.empty(0, object)
            out[f"map/{layer}"] = with_geo_metadata(table, extra, geometries)
    for layer in DICT_LAYERS:
        table, layer_problems = _dict_layer_table(maps, layer, entries)
        problems += layer_problems
        if table is not None:
            out[f"map/{layer}"] = table
    if problems:
        raise ProblemsFound(problems)
    centerlines, lines = _centerlines(maps)
    out["map/lane_centerlines"] = with_geo_metadata(centerlines, extra | {"resolution_m": CENTERLINE_RESOLUTION_M}, lines)
    for name, table in out.items():  # the files carry their own GeoParquet metadata: checked, not cast
        check_columns(table, schema_for(name))
    ctx.files += entries
    return out


def _location_column(maps: list[source.MapRead], counts: list[int]) -> pa.Array:
    return pa.DictionaryArray.from_arrays(pa.array(np.repeat(np.arange(len(maps), dtype=np.int32), counts)),
                                          pa.array([m.location for m in maps], pa.string())).cast(pa.string())


def _typed(maps, layer, entries, records_of=None) -> tuple[pa.Table | None, list[int], list[Problem]]:
    """Layer `layer` of every map typed together (from `records_of`, per-lane stand-in records of the same maps,
    when the layer is a dict), its record count per map, and what export needs recorded per file."""
    typed, problems = source.layer_columns(records_of or maps, layer)
    counts = [len(m.data[layer]) for m in maps]
    if typed is None:
        return None, counts, problems
    _record_facts(entries, layer, typed.columns, typed.struct_fields, typed.starts, counts)
    return typed.columns.table, counts, problems


def _layer_table(maps, layer, entries) -> tuple[pa.Table | None, list[Problem]]:
    table, counts, problems = _typed(maps, layer, entries)
    if table is None:
        return None, problems
    table = table.add_column(0, "location", _location_column(maps, counts))
    geometries = np.concatenate([m.geometry[layer] for m in maps]) if maps else np.empty(0, object)
    wkb, bbox = geometry_columns(geometries)
    return table.append_column("geometry", wkb).append_column("bbox", bbox), problems


def _dict_layer_table(maps, layer, entries) -> tuple[pa.Table | None, list[Problem]]:
    """arcline_path_3 ({lane: [path, ...]}) and connectivity ({lane: {incoming, outgoing}}): one row per lane,
    in the file's key order."""
    fake = []
    for m in maps:  # a per-lane record, typed like the list layers
        values = m.data[layer]
        records = [{"paths": v} for v in values.values()] if layer == "arcline_path_3" else list(values.values())
        fake.append(source.MapRead(m.location, m.path, {layer: records}))
    table, counts, problems = _typed(maps, layer, entries, records_of=fake)
    if table is None:
        return None, problems
    if table.num_columns == 0:
        table = pa.table({"incoming": pa.array([], pa.list_(pa.string())), "outgoing": pa.array([], pa.list_(pa.string()))}) \
            if layer == "connectivity" else pa.table({"paths": pa.array([], pa.string())})
    lanes = [t for m in maps for t in m.data[layer]]
    table = table.add_column(0, "lane_token", pa.array(lanes, pa.string()))
    return table.add_column(0, "location", _location_column(maps, counts)), problems


def _record_facts(entries, layer, columns, struct_fields, starts, counts) -> None:
    """Per map file: what export needs to write this layer back (positions local to the file)."""
    for entry, start, count in zip(entries, starts, counts):
        stop = start + count
        facts = {"keys": columns.keys}
        if columns.json_fields:
            facts["json_fields"] = columns.json_fields
        if struct_fields:
            facts["struct_fields"] = struct_fields
        facts |= range_facts(columns, start, stop)
        entry["layers"][layer] = facts


def _centerlines(maps: list[source.MapRead]) -> tuple[pa.Table, np.ndarray]:
    """Every lane and lane connector (the devkit's `discretize_centerlines` order) at CENTERLINE_RESOLUTION_M."""
    columns: dict[str, list] = {"location": [], "token": [], "layer": []}
    paths = []
    for m in maps:
        for layer in ("lane", "lane_connector"):
            tokens = [r["token"] for r in m.data[layer]]
            columns["location"] += [m.location] * len(tokens)
            columns["token"] += tokens
            columns["layer"] += [layer] * len(tokens)
            paths += [m.data["arcline_path_3"].get(t, []) for t in tokens]
    poses, counts = discretize_lanes(paths, CENTERLINE_RESOLUTION_M)
    offsets = pa.array(np.r_[0, np.cumsum(counts)].astype(np.int32))
    table = pa.table({**{k: pa.array(v, pa.string()) for k, v in columns.items()},
                      **{name: pa.ListArray.from_arrays(offsets, pa.array(poses[:, k])) for k, name in enumerate(("x_m", "y_m", "yaw_rad"))}})
    lines = np.full(len(counts), None, dtype=object)
    ok = np.flatnonzero(counts >= 2)
    if len(ok):
        keep = np.repeat(counts >= 2, counts)
        lines[ok] = shapely.linestrings(poses[keep, :2], indices=np.repeat(np.arange(len(ok)), counts[ok]))
    wkb, bbox = geometry_columns(lines)
    return table.append_column("geometry", wkb).append_column("bbox", bbox), lines


BUILDER = Builder("map", build, scope="whole", group_by="location", wanted=wanted)
