"""Map queries over the converted map (`map/<layer>/`), vectorised, with the devkit's answers.

`Dataset.map(location)` reads one location's layers (WKB -> shapely 2 arrays; an STRtree per layer,
built on first use). Every query takes arrays and answers for all of them at once; none loops over records:

- `layers_on_point(x, y)`: = `NuScenesMap.layers_on_point` for each point: per polygon layer, the first record
  (file order) whose polygon strictly contains the point (the devkit's `point.within`), '' where none.
- `records_in_patch(box, mode)`: = `get_records_in_patch`. Polygon layers use the geometry (`intersects` /
  `within`, drivable_area as the MultiPolygon of its polygons); line layers keep the devkit's quirk: a line
  "intersects" a patch when one of its *nodes* lies strictly inside it and is "within" when all do (a line
  crossing the patch with no node inside is not reported; lines without nodes never are).
- `closest_lane(x, y, radius_m)`: = `get_closest_lane`: among lanes and lane connectors whose polygon
  intersects the square of half-side `radius_m`, the one with the nearest 0.5 m centreline pose; ties go to the
  later candidate (lanes before connectors, file order), as the devkit's `<=` does; '' where none.
- `map_mask(patch_box, patch_angle_deg, layers, canvas_size)`: = `get_map_mask` pixel for pixel (`map.mask`).
- `discretize_lanes(tokens, resolution_m)`: = `discretize_lanes` (`map.centerlines`).
- `record_on_point`, `bounds`, `next_roads`: = `record_on_point`, `get_bounds`, `get_next_roads` (`map.roads`).
- `arcline_path(token)`, `incoming_lanes`, `outgoing_lanes`: = `get_arcline_path`, `get_incoming_lane_ids`,
  `get_outgoing_lane_ids`; the arcline helpers (`project_pose_to_lane`, `length_of_lane`, curvature) are
  `nuparquet.map.arcline`.

Longer than our ~300-line norm: it is the one face of a location's map, and every method keeps the devkit name it
answers for beside its docstring; the work is done in `map.roads`, `map.mask`, `map.centerlines`, `map.arcline`.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import pyarrow as pa
import shapely
from shapely import STRtree

from nuparquet.map.centerlines import discretize_lanes as _discretize
from nuparquet.map.lookup import _Layer, _Parts, records_on_point
from nuparquet.map.layers import LANE_LAYERS, LINE_LAYERS, LOOKUP_POLYGON_LAYERS, NON_GEOMETRIC_LAYERS, POLYGON_LAYERS



def _read(dataset, layer: str, location: str, columns: list[str]) -> pa.Table:
    """One location's rows of `map/<layer>` (file order), through the dataset's scans (local or remote)."""
    return dataset.scan(f"map/{layer}").filter(pl.col("location") == location).select(columns).collect().to_arrow()


class _LayerRecords(dict):
    """layer -> `_Layer` (tokens and geometry of its records, file order), each layer read on first use."""

    def __init__(self, dataset, location: str) -> None:
        super().__init__()
        self._dataset, self._location = dataset, location

    def __missing__(self, layer: str) -> _Layer:
        table = _read(self._dataset, layer, self._location, ["token", "geometry"])
        self[layer] = _Layer(np.asarray(table.column("token").to_pylist(), dtype=object),
                             shapely.from_wkb(table.column("geometry").to_numpy(zero_copy_only=False)))
        return self[layer]


class MapLayers:
    """One location's map layers (`MapLayers.open`): `layers` (token and geometry of each polygon and line layer
    record, file order), `parts` (the polygons the devkit walks); the line layers' nodes and the lanes' arcline
    paths are read on first use (`line_nodes`, `arcline_path_3`): point lookups need neither."""

    def __init__(self, location: str, layers: dict[str, _Layer], parts: dict[str, _Parts], dataset=None, *,
                 line_nodes: dict | None = None, arcline_path_3: dict | None = None) -> None:
        self.location = location
        self.layers = layers
        self.parts = parts
        self.dataset = dataset  # record fields are read from it on first use
        self._records: dict[str, pl.DataFrame] = {}
        self._line_nodes = line_nodes
        self._arcline = arcline_path_3
        self._centerlines: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._lane_tree: STRtree | None = None

    @classmethod
    def open(cls, dataset, location: str) -> MapLayers:
        """One location's map from the `map/` datasets of `dataset` (a `Dataset`; `Dataset.map(location)` is the
        usual way here, and keeps what it read).

        Raises:
            UsageError: the output has no map datasets, or no map of `location` (the message lists those it has).
        """
        from nuparquet.errors import UsageError

        if "map/lane" not in dataset.datasets:
            raise UsageError(f"{dataset.root} has no map/ datasets: convert a dataroot holding maps/expansion/*.json "
                             "(without --no-map)")
        locations = sorted(dataset.scan("map/lane").select("location").unique().collect()["location"].to_list())
        if location not in locations:
            raise UsageError(f"no map of {location!r} in {dataset.root}; maps: {', '.join(locations) or '(none)'}")
        layers, parts = _LayerRecords(dataset, location), {}
        for layer in LOOKUP_POLYGON_LAYERS:
            if layer == "drivable_area":
                polygons = _read(dataset, "polygon", location, ["token", "geometry"])
                polygon_geometry = dict(zip(polygons.column("token").to_pylist(),
                                            shapely.from_wkb(polygons.column("geometry").to_numpy(zero_copy_only=False))))
                lists = _read(dataset, layer, location, ["polygon_tokens"]).column("polygon_tokens").to_pylist()
                owner = np.repeat(np.arange(len(lists)), [len(t) for t in lists])
                geometry = np.array([polygon_geometry[t] for tokens in lists for t in tokens], dtype=object)
                parts[layer] = _Parts(owner, geometry)
            else:
                parts[layer] = _Parts(np.arange(len(layers[layer].tokens)), layers[layer].geometry)
        return cls(location, layers, parts, dataset)

    @property
    def line_nodes(self) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """layer -> ((N, 2) node xy of each line record in order, (N,) record of each node, (R,) node counts)."""
        if self._line_nodes is None:
            dataset, location = self.dataset, self.location
            nodes = _read(dataset, "node", location, ["token", "x", "y"])
            node_index = {t: i for i, t in enumerate(nodes.column("token").to_pylist())}
            node_xy = np.c_[nodes.column("x").to_numpy(), nodes.column("y").to_numpy()]
            lines = _read(dataset, "line", location, ["token", "node_tokens"])
            line_tokens = dict(zip(lines.column("token").to_pylist(), lines.column("node_tokens").to_pylist()))
            line_nodes = {}
            for layer in LINE_LAYERS:
                refs = _read(dataset, layer, location, ["line_token"]).column("line_token").to_pylist()
                lists = [line_tokens[t] for t in refs]
                counts = np.array([len(t) for t in lists], dtype=np.int64)
                flat = np.fromiter((node_index[t] for tokens in lists for t in tokens), np.int64, int(counts.sum()))
                line_nodes[layer] = (node_xy[flat].reshape(-1, 2), np.repeat(np.arange(len(lists)), counts), counts)
            self._line_nodes = line_nodes
        return self._line_nodes

    @property
    def arcline_path_3(self) -> dict[str, list[dict]]:
        """lane token -> its arcline paths (lanes and lane connectors)."""
        if self._arcline is None:
            paths = _read(self.dataset, "arcline_path_3", self.location, ["lane_token", "paths"])
            values = paths.column("paths").to_pylist()
            if values and isinstance(values[0], str):  # kept as JSON text
                import json
                values = [json.loads(v) for v in values]
            self._arcline = dict(zip(paths.column("lane_token").to_pylist(), values))
        return self._arcline

    # -- records and their fields -----------------------------------------------------------------------------

    def records(self, layer: str) -> pl.DataFrame:
        """Every record of `layer` of this map, file order, with the map file's fields (geometry as WKB), read once."""
        if layer not in self._records:
            if self.dataset is None:
                raise ValueError("this MapLayers was built without its dataset: records cannot be read")
            self._records[layer] = (self.dataset.scan(f"map/{layer}").filter(pl.col("location") == self.location)
                                    .drop("location").collect())
        return self._records[layer]

    def record(self, layer: str, token: str) -> dict:
        """One record of `layer` as the map file holds it (the devkit's `get(layer, token)`, without its shortcuts)."""
        rows = self.records(layer).filter(pl.col("token") == token)
        if rows.is_empty():
            from nuparquet.errors import UsageError

            raise UsageError(f"no {layer} record {token!r} in the map of {self.location}")
        return rows.drop("geometry", "bbox", strict=False).row(0, named=True)

    def record_field(self, layer: str, token: str, name: str):
        return self.record(layer, token)[name]

    def line_node_tokens(self, line_token: str) -> list[str]:
        """The node tokens of a `line` record."""
        return self.record("line", line_token)["node_tokens"]

    def exterior_nodes(self, layer: str) -> dict[str, frozenset[str]]:
        """{record token: its polygon's exterior node tokens} of a polygon layer other than drivable_area (the
        devkit's `exterior_node_tokens` shortcut)."""
        polygons = self.records("polygon").select("token", "exterior_node_tokens")
        nodes = dict(zip(polygons["token"].to_list(), polygons["exterior_node_tokens"].to_list()))
        rows = self.records(layer).select("token", "polygon_token")
        return {t: frozenset(nodes.get(p) or ()) for t, p in zip(rows["token"].to_list(), rows["polygon_token"].to_list())}

    # -- the devkit's helpers by record -----------------------------------------------------------------------

    def record_on_point(self, x: float, y: float, layer: str) -> str:
        """The first record of polygon layer `layer` holding (x, y), '' where none (`record_on_point`)."""
        if layer not in POLYGON_LAYERS:
            raise ValueError(f"{layer} is not a polygon layer")
        return str(self.layers_on_point(x, y, [layer])[layer][0])

    def bounds(self, layer: str, token: str) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of a record (`get_bounds`; `map.roads.bounds`)."""
        from nuparquet.map.roads import bounds

        return bounds(self, layer, token)

    def next_roads(self, x: float, y: float) -> dict[str, list[str]]:
        """The road segments, road blocks and lanes that may follow the road at (x, y) (`get_next_roads`)."""
        from nuparquet.map.roads import next_roads

        return next_roads(self, x, y)

    def records_in_radius(self, x: float, y: float, radius_m: float, layer_names=None,
                          mode: str = "intersect") -> dict[str, list[str]]:
        """`records_in_patch` of the square of half-side `radius_m` around (x, y) (`get_records_in_radius`)."""
        return self.records_in_patch((x - radius_m, y - radius_m, x + radius_m, y + radius_m), layer_names, mode)

    def arcline_path(self, lane_token: str) -> list[dict]:
        """The lane's arcline paths (`get_arcline_path`); UsageError for a token without any."""
        paths = self.arcline_path_3.get(lane_token)
        if not paths:
            from nuparquet.errors import UsageError

            raise UsageError(f"lane {lane_token!r} has no arcline path in the map of {self.location}")
        return paths

    def incoming_lanes(self, lane_token: str) -> list[str]:
        """Lanes that end where this one starts (`get_incoming_lane_ids`)."""
        return self._connected(lane_token, "incoming")

    def outgoing_lanes(self, lane_token: str) -> list[str]:
        """Lanes that start where this one ends (`get_outgoing_lane_ids`)."""
        return self._connected(lane_token, "outgoing")

    def _connected(self, lane_token: str, direction: str) -> list[str]:
        rows = self.records("connectivity").filter(pl.col("lane_token") == lane_token)
        if rows.is_empty():
            from nuparquet.errors import UsageError

            raise UsageError(f"{lane_token!r} is not a lane of the map of {self.location} (no connectivity)")
        values = rows[direction][0]
        return [] if values is None else values.to_list()

    # -- point queries ----------------------------------------------------------------------------------------


    # -- point queries ----------------------------------------------------------------------------------------

    def layers_on_point(self, x, y, layer_names: tuple[str, ...] | list[str] | None = None) -> dict[str, np.ndarray]:
        """{layer: (N,) token of the first record containing each point, '' where none}."""
        records = self.records_on_point(x, y, layer_names)
        out = {}
        for layer, found in records.items():
            tokens = np.full(len(found), "", dtype=object)
            hit = found >= 0
            tokens[hit] = self.layers[layer].tokens[found[hit]]
            out[layer] = tokens
        return out

    def records_on_point(self, x, y, layer_names: tuple[str, ...] | list[str] | None = None) -> dict[str, np.ndarray]:
        """{layer: (N,) int64 row (file order) of the first record containing each point, -1 where none}: what
        `layers_on_point` answers, as record rows (`layers[layer].tokens[row]`; `map.lookup`)."""
        layer_names = layer_names or POLYGON_LAYERS
        for layer in layer_names:
            if layer not in LOOKUP_POLYGON_LAYERS:  # lane_connector: an extension (the devkit refuses it)
                raise ValueError(f"{layer} is not a polygon layer")
        return records_on_point({layer: self.parts[layer] for layer in layer_names}, x, y)

    def records_in_patch(self, box_coords: tuple[float, float, float, float],
                         layer_names: tuple[str, ...] | list[str] | None = None,
                         mode: str = "intersect") -> dict[str, list[str]]:
        """{layer: tokens of the records intersecting / within the patch (x_min, y_min, x_max, y_max)}."""
        if mode not in ("intersect", "within"):
            raise ValueError(f"Mode {mode} is not valid, choice=('intersect', 'within')")
        x_min, y_min, x_max, y_max = box_coords
        patch = shapely.box(x_min, y_min, x_max, y_max)
        out = {}
        for layer in layer_names or NON_GEOMETRIC_LAYERS:
            if layer in LOOKUP_POLYGON_LAYERS:
                records = self.layers[layer]
                index = records.tree.query(patch, predicate="intersects" if mode == "intersect" else "contains") \
                    if len(records.geometry) else np.zeros(0, np.int64)
                out[layer] = records.tokens[np.sort(index)].tolist()
            elif layer in LINE_LAYERS:
                xy, owner, counts = self.line_nodes[layer]
                inside = (xy[:, 0] < x_max) & (xy[:, 0] > x_min) & (xy[:, 1] < y_max) & (xy[:, 1] > y_min)
                n_inside = np.bincount(owner, weights=inside, minlength=len(counts))
                keep = n_inside > 0 if mode == "intersect" else (n_inside == counts) & (counts > 0)
                out[layer] = self.layers[layer].tokens[keep].tolist()
            else:
                raise ValueError(f"{layer} is not a valid layer")
        return out

    def centerlines(self, resolution_m: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) poses of every lane then every lane connector (file order) and (L,) pose counts, cached."""
        if resolution_m not in self._centerlines:
            tokens = np.concatenate([self.layers[layer].tokens for layer in LANE_LAYERS])
            self._centerlines[resolution_m] = _discretize([self.arcline_path_3.get(t, []) for t in tokens], resolution_m)
        return self._centerlines[resolution_m]

    def discretize_lanes(self, tokens: list[str], resolution_m: float) -> dict[str, list[tuple[float, float, float]]]:
        """{token: the lane's centreline poses (x, y, yaw)} for lanes and lane connectors of this map (the devkit's
        `discretize_lanes`); UsageError naming the tokens that are neither."""
        unknown = [t for t in tokens if t not in self.arcline_path_3]
        if unknown:
            from nuparquet.errors import UsageError

            raise UsageError(f"no lane or lane connector {', '.join(map(repr, unknown[:5]))}"
                             f"{' ...' if len(unknown) > 5 else ''} in the map of {self.location}")
        poses, counts = _discretize([self.arcline_path_3.get(t, []) for t in tokens], resolution_m)
        starts = np.r_[0, np.cumsum(counts)]
        return {t: [tuple(p) for p in poses[starts[i]:starts[i + 1]].tolist()] for i, t in enumerate(tokens)}

    def closest_lane(self, x, y, radius_m: float = 5.0, *, chunk: int = 4096) -> np.ndarray:
        """(N,) token of the closest lane or lane connector to each point within `radius_m` ('' where none)."""
        x, y = np.atleast_1d(np.asarray(x, np.float64)), np.atleast_1d(np.asarray(y, np.float64))
        lanes = np.concatenate([self.layers[layer].geometry for layer in LANE_LAYERS])
        tokens = np.concatenate([self.layers[layer].tokens for layer in LANE_LAYERS])
        poses, counts = self.centerlines(0.5)
        starts = np.r_[0, np.cumsum(counts)[:-1]]
        if self._lane_tree is None:
            self._lane_tree = STRtree(lanes)
        tree = self._lane_tree
        out = np.full(len(x), "", dtype=object)
        for lo in range(0, len(x), chunk):
            xs, ys = x[lo:lo + chunk], y[lo:lo + chunk]
            boxes = shapely.box(xs - radius_m, ys - radius_m, xs + radius_m, ys + radius_m)
            point_i, lane_i = tree.query(boxes, predicate="intersects")
            has = counts[lane_i] > 0
            point_i, lane_i = point_i[has], lane_i[has]
            if not len(point_i):
                continue
            n = counts[lane_i]
            pair = np.repeat(np.arange(len(lane_i)), n)
            pose = np.repeat(starts[lane_i] - np.r_[0, np.cumsum(n)[:-1]], n) + np.arange(n.sum())
            d = poses[pose, :2] - np.c_[xs[point_i], ys[point_i]][pair]
            distance = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
            pair_min = np.minimum.reduceat(distance, np.r_[0, np.cumsum(n)[:-1]])
            # per point: the smallest distance, ties to the latest candidate (the devkit's `<=` scan)
            order = np.lexsort((-lane_i, pair_min, point_i))
            first = np.r_[True, point_i[order][1:] != point_i[order][:-1]]
            best = order[first]
            out[lo + point_i[best]] = tokens[lane_i[best]]
        return out

    def map_mask(self, patch_box: tuple[float, float, float, float], patch_angle_deg: float,
                 layer_names: tuple[str, ...] | list[str] | None = None,
                 canvas_size: tuple[int, int] = (100, 100)) -> np.ndarray:
        """(C, H, W) uint8 masks of the patch [x_center, y_center, height, width] rotated by `patch_angle_deg`
        (`nuparquet.map.mask`)."""
        from nuparquet.map.mask import map_mask

        return map_mask(self, patch_box, patch_angle_deg, layer_names, canvas_size)
