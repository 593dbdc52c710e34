"""The nuScenes map expansion: `DATAROOT/maps/expansion/<location>.json` (version 1.3).

Read as the devkit reads it (`NuScenesMap.__init__`: `json.load` of the whole file, maps older than 1.3
refused) and checked: every token a polygon, line or layer record names must exist. Each list layer becomes a
typed table (`json_records`: exactly reversible), nested fields (`holes`, `items`, `lane_divider_segments`)
as Arrow lists of structs when they come back byte-identical, else as their JSON text; the top-level dicts
`arcline_path_3` and `connectivity` become one row per lane. Geometry is built in vectorised form (shapely 2
arrays): nodes -> rings -> polygons, lines; the geometric layers take theirs from `polygon_token(s)` /
`line_token` exactly as `extract_polygon` / `extract_line` build them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from itertools import chain, repeat
from operator import itemgetter
from pathlib import Path

import numpy as np
import pyarrow as pa
import shapely

from nuparquet.map.layers import DICT_LAYERS, LINE_LAYERS, LIST_LAYERS, LOOKUP_POLYGON_LAYERS
from nuparquet.problems import Problem, echo
from nuparquet.sources.json_records import Columns, Located, to_columns

FOLDER = "maps/expansion"
MIN_VERSION = (1, 3)
# South-west corner of each nuScenes map ([lat, lon], WGS 84), from the devkit's NuScenesMap docstring.
ORIGIN_LAT_LON = {"boston-seaport": [42.336849169438615, -71.05785369873047],
                  "singapore-onenorth": [1.2882100868743724, 103.78475189208984],
                  "singapore-hollandvillage": [1.2993652317780957, 103.78217697143555],
                  "singapore-queenstown": [1.2782562240223188, 103.76741409301758]}


@dataclass
class MapRead:
    """One checked map file: its records as parsed (key order kept) and the geometry of every list layer."""

    location: str
    path: str  # relative to the dataroot
    data: dict
    geometry: dict[str, np.ndarray] = field(default_factory=dict)  # layer -> (R,) shapely geometries (None: none)

    @property
    def scalars(self) -> dict:
        """Top-level values that are not layers (version, canvas_edge, anything newer), as in the file."""
        return {k: v for k, v in self.data.items() if k not in LIST_LAYERS + DICT_LAYERS}


@dataclass
class LayerColumns:
    """A layer's records of every map, typed together (`json_records`), plus the nested fields kept as Arrow
    lists of structs because they come back byte-identical."""

    columns: Columns
    struct_fields: list[str]
    starts: list[int]  # first row of each map


def discover(dataroot: Path) -> list[Path]:
    """Map files (relative to the dataroot), by name."""
    return [p.relative_to(dataroot) for p in sorted((dataroot / FOLDER).glob("*.json"))]


def _version_tuple(version) -> tuple[int, ...] | None:
    try:
        return tuple(int(part) for part in str(version).split("."))
    except ValueError:
        return None


def read_map(dataroot: Path, relative: Path) -> tuple[MapRead | None, list[Problem]]:
    name = relative.as_posix()
    try:
        data = json.loads((dataroot / relative).read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        return None, [Problem(name, f"not valid JSON ({exc}); a truncated or damaged map file")]
    except OSError as exc:
        return None, [Problem(name, f"cannot be read ({exc.strerror or exc})")]
    if not isinstance(data, dict):
        return None, [Problem(name, f"must be a JSON object (a map expansion), not a {type(data).__name__}")]
    version = data.get("version", "1.0")  # the devkit's default for files without one
    parsed = _version_tuple(version)
    if parsed is None or parsed < MIN_VERSION:
        return None, [Problem(name, f"map version {echo(version)} is older than 1.3 (or not a version): nuparquet, like "
                                    "the devkit, reads only map expansion 1.3 and later; download the current maps "
                                    "from https://www.nuscenes.org/download")]
    missing = [k for k in LIST_LAYERS + DICT_LAYERS + ("canvas_edge",) if k not in data]
    if missing:
        return None, [Problem(name, f"lacks the layer(s) {', '.join(missing)} of a v1.3 map expansion")]
    problems = [Problem(name, f"{layer} must be a list of objects with a token") for layer in LIST_LAYERS
                if not _records_with_tokens(data[layer])]
    problems += [Problem(name, f"{layer} must be an object keyed by lane token") for layer in DICT_LAYERS
                 if not isinstance(data[layer], dict)]
    if problems:
        return None, problems
    problems = _check_references(name, data)
    if problems:
        return None, problems
    read = MapRead(relative.stem, name, data)
    _add_geometry(data, read.geometry)
    return read, []


def _records_with_tokens(records) -> bool:
    """A list of JSON objects, each with a string `token` (json.loads makes exactly dict and str)."""
    if type(records) is not list:
        return False
    if not all(type(r) is dict for r in records):
        return False
    return all(type(t) is str for t in map(dict.get, records, repeat("token", len(records))))


def layer_columns(maps: list[MapRead], layer: str) -> tuple[LayerColumns | None, list[Problem]]:
    """The records of `layer` in every map (map order, then file order), typed together."""
    records, starts = [], []
    for m in maps:
        starts.append(len(records))
        records += m.data[layer]
    columns, problems = to_columns(records, Located([m.path for m in maps], starts), f"{layer} record")
    if columns is None:
        return None, problems
    return LayerColumns(columns, _structure_json_fields(columns, records), starts), problems


def _check_references(name: str, data: dict) -> list[Problem]:
    """Every node a line or polygon names, and every polygon / line a layer record names, exists. Whole lists are
    checked as sets first; only a list that names something unknown is walked record by record to say where."""
    nodes = {r["token"] for r in data["node"]}
    problems = [] if _all_known(_node_lists(data), nodes) else _node_problems(name, data, nodes)
    if len(problems) >= 20:
        return problems
    polygons = {r["token"] for r in data["polygon"]}
    lines = {r["token"] for r in data["line"]}
    for layer in LOOKUP_POLYGON_LAYERS + LINE_LAYERS:
        key, known, what = (("polygon_tokens" if layer == "drivable_area" else "polygon_token"), polygons, "polygon") \
            if layer in LOOKUP_POLYGON_LAYERS else ("line_token", lines, "line")
        values = [record.get(key) for record in data[layer]]
        if layer == "drivable_area":
            if all(type(v) is list for v in values) and _all_known(values, known):
                continue
        elif _all_known([values], known) and None not in values:
            continue
        for i, (record, value) in enumerate(zip(data[layer], values)):
            if isinstance(value, list) != (layer == "drivable_area"):  # a list of tokens there, one token elsewhere
                shape = f"a list of {what} tokens" if layer == "drivable_area" else f"one {what} token"
                problems.append(Problem(name, f"{layer} field {key} must be {shape}, not {echo(value)}", i, record["token"]))
                continue
            # not str: unknown (a nested list or null would be unhashable or a missing token further on)
            absent = [t for t in (value if isinstance(value, list) else [value]) if type(t) is not str or t not in known]
            if absent:
                problems.append(Problem(name, f"{layer} field {key} names {what} {echo(absent[0])}, which is not in "
                                              f"the map's {what} list", i, record["token"]))
            if len(problems) >= 20:
                return problems
    return problems


def _node_lists(data: dict):
    """Every node-token list of the lines and polygons (exteriors, holes); a malformed one as it is."""
    for record in data["line"]:
        yield record.get("node_tokens")
    for record in data["polygon"]:
        yield record.get("exterior_node_tokens")
        holes = record.get("holes")
        if not isinstance(holes, list):
            yield None
            continue
        for hole in holes:
            yield hole.get("node_tokens") if isinstance(hole, dict) else None


def _all_known(lists, known: set) -> bool:
    """Each of `lists` is a list whose items all are in `known` (hashable items: one C-level set check)."""
    try:
        return all(type(tokens) is list and known.issuperset(tokens) for tokens in lists)
    except TypeError:  # an unhashable item (a nested list): the slow path names it
        return False


def _node_problems(name: str, data: dict, nodes: set) -> list[Problem]:
    problems: list[Problem] = []
    for layer, keys in (("line", ("node_tokens",)), ("polygon", ("exterior_node_tokens", "holes"))):
        for i, record in enumerate(data[layer]):
            for key in keys:
                value = record.get(key)
                lists = [h.get("node_tokens") if isinstance(h, dict) else None for h in value] \
                    if key == "holes" and isinstance(value, list) else [value]
                for tokens in lists:
                    if not isinstance(tokens, list):
                        problems.append(Problem(name, f"{layer} field {key} must be a list of node tokens", i, record["token"]))
                        continue
                    absent = next((t for t in tokens if t not in nodes), None)
                    if absent is not None:
                        problems.append(Problem(name, f"{layer} names node {echo(absent)} ({key}), which is not in "
                                                      "the map's node list", i, record["token"]))
            if len(problems) >= 20:
                return problems
    return problems


def _structure_json_fields(columns: Columns, records: list[dict]) -> list[str]:
    """Turn JSON-text fields into Arrow lists/structs where that gives back exactly the same JSON (a hole list,
    a lane's divider segments); returns the fields converted. `records`: the parsed records typed in `columns`."""
    converted = []
    for name in list(columns.json_fields):
        values = [r[name] for r in records]
        try:
            array = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError, pa.ArrowNotImplementedError):
            continue
        # repr, not ==: the same values with the same types (1 is not 1.0) and keys in the same order, as their JSON
        if not pa.types.is_null(array.type) and repr(array.to_pylist()) == repr(values):
            index = columns.table.column_names.index(name)
            columns.table = columns.table.set_column(index, name, array)
            columns.json_fields.remove(name)
            converted.append(name)
    return converted


def _node_xy(data: dict) -> tuple[dict[str, int], np.ndarray]:
    nodes = data["node"]
    index = dict(zip(map(itemgetter("token"), nodes), range(len(nodes))))
    xy = np.fromiter(chain.from_iterable(map(itemgetter("x", "y"), nodes)), np.float64, 2 * len(nodes))
    return index, xy.reshape(-1, 2)


def _rings(token_lists: list[list[str]], index: dict[str, int], xy: np.ndarray) -> np.ndarray:
    """(K,) closed linear rings from K node-token lists (each at least 3 nodes), built in one shapely call."""
    lengths = np.fromiter(map(len, token_lists), np.int64, len(token_lists))
    flat = np.fromiter((index[t] for tokens in token_lists for t in tokens), np.int64, int(lengths.sum()))
    if not len(token_lists):
        return np.empty(0, dtype=object)
    return shapely.linearrings(xy[flat], indices=np.repeat(np.arange(len(token_lists)), lengths))


def _add_geometry(data: dict, out: dict[str, np.ndarray]) -> None:
    index, xy = _node_xy(data)
    out["node"] = shapely.points(xy)
    # lines: LineString of their nodes; fewer than 2 nodes (a few Queenstown lines have none) -> no geometry
    line_nodes = [r["node_tokens"] for r in data["line"]]
    lengths = np.array([len(n) for n in line_nodes], dtype=np.int64)
    lines = np.full(len(line_nodes), None, dtype=object)
    ok = np.flatnonzero(lengths >= 2)
    if len(ok):
        flat = np.fromiter((index[t] for i in ok for t in line_nodes[i]), np.int64, int(lengths[ok].sum()))
        lines[ok] = shapely.linestrings(xy[flat], indices=np.repeat(np.arange(len(ok)), lengths[ok]))
    out["line"] = lines
    # polygons: the exterior, then the non-empty holes (the devkit drops empty ones), one polygon per record
    # (a ring of fewer than 3 nodes makes no polygon, for the devkit's shapely either: no geometry, null)
    rings, owners = [], []
    n_polygons = len(data["polygon"])
    for i, record in enumerate(data["polygon"]):
        holes = [h["node_tokens"] for h in record["holes"] if h["node_tokens"]]
        if len(record["exterior_node_tokens"]) < 3 or any(len(h) < 3 for h in holes):
            continue
        for ring in [record["exterior_node_tokens"]] + holes:
            rings.append(ring)
            owners.append(i)
    polygons = np.full(n_polygons, None, dtype=object)
    if rings:
        owners = np.array(owners, dtype=np.int64)
        built = shapely.polygons(_rings(rings, index, xy), indices=np.unique(owners, return_inverse=True)[1])
        polygons[np.unique(owners)] = built
    out["polygon"] = polygons
    polygon_index = {r["token"]: i for i, r in enumerate(data["polygon"])}
    line_index = {r["token"]: i for i, r in enumerate(data["line"])}
    for layer in LOOKUP_POLYGON_LAYERS:
        records = data[layer]
        if layer == "drivable_area":
            parts = [[polygon_index[t] for t in r["polygon_tokens"]] for r in records]
            geoms = np.array([shapely.multipolygons([g for g in polygons[p] if g is not None]) for p in parts], dtype=object) \
                if records else np.empty(0, dtype=object)
        else:
            geoms = polygons[np.fromiter((polygon_index[r["polygon_token"]] for r in records), np.int64, len(records))]
        out[layer] = geoms
    for layer in LINE_LAYERS:
        records = data[layer]
        out[layer] = lines[np.fromiter((line_index[r["line_token"]] for r in records), np.int64,
                                                   len(records))]
