"""The map around a scene's route as Foxglove geometry: polygon layers as triangle lists, divider layers as line
segments, clipped to the route's bounding box plus a margin.

Polygons are clipped (`shapely.clip_by_rect`) and triangulated with GEOS' constrained Delaunay triangulation
(holes and edges respected), all geometries of a layer in one call; lines become LINE_LIST segments (each
consecutive pair of a line's vertices). z = 0: the map is flat, as the devkit's.
"""

from __future__ import annotations


import numpy as np
import shapely

# Bottom to top (Foxglove draws later entities over earlier ones at equal depth): (layer, kind, RGBA 0..1, z m).
LAYER_STYLE: tuple[tuple[str, str, tuple[float, float, float, float], float], ...] = (
    ("drivable_area", "triangles", (0.35, 0.35, 0.38, 0.6), -0.05),
    ("carpark_area", "triangles", (0.45, 0.35, 0.25, 0.6), -0.04),
    ("walkway", "triangles", (0.30, 0.50, 0.30, 0.6), -0.04),
    ("lane", "triangles", (0.42, 0.42, 0.45, 0.5), -0.03),
    ("ped_crossing", "triangles", (0.80, 0.80, 0.80, 0.6), -0.02),
    ("stop_line", "triangles", (0.85, 0.20, 0.20, 0.6), -0.02),
    ("road_divider", "lines", (0.95, 0.80, 0.10, 1.0), 0.0),
    ("lane_divider", "lines", (0.90, 0.90, 0.90, 1.0), 0.0),
)


def route_box(ego_xy_m: np.ndarray, margin_m: float) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of the ego positions (N, 2) grown by `margin_m`."""
    low, high = ego_xy_m.min(axis=0) - margin_m, ego_xy_m.max(axis=0) + margin_m
    return float(low[0]), float(low[1]), float(high[0]), float(high[1])


def triangles(geometries: np.ndarray, z_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(3T, 3) corner points of the constrained Delaunay triangles of every polygon in `geometries` and (3T,)
    indices 0..3T-1 (each triangle its own three points)."""
    polygons = [g for g in geometries if g is not None and not shapely.is_empty(g)]
    if not polygons:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    pieces = shapely.get_parts(shapely.make_valid(np.asarray(polygons, dtype=object)))
    pieces = pieces[shapely.get_type_id(pieces) == 3]  # polygons only (a clip or make_valid may leave lines)
    if not len(pieces):
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    parts = shapely.get_parts(shapely.constrained_delaunay_triangles(pieces))
    parts = parts[shapely.get_type_id(parts) == 3]
    rings = shapely.get_coordinates(shapely.get_exterior_ring(parts)).reshape(len(parts), 4, 2)[:, :3]
    xy = rings.reshape(-1, 2)
    return np.c_[xy, np.full(len(xy), z_m)], np.arange(len(xy), dtype=np.int64)


def segments(geometries: np.ndarray, z_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) vertices of every line in `geometries` and (2S,) indices: a segment between each consecutive pair
    of vertices of the same line."""
    lines = [g for g in geometries if g is not None and not shapely.is_empty(g)]
    if not lines:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    coords, owner = shapely.get_coordinates(shapely.get_parts(np.asarray(lines, dtype=object)), return_index=True)
    starts = np.flatnonzero(owner[:-1] == owner[1:])  # vertex i joins i + 1 within the same part
    indices = np.c_[starts, starts + 1].ravel()
    return np.c_[coords, np.full(len(coords), z_m)], indices.astype(np.int64)


def map_layers_near(dataset, location: str, box: tuple[float, float, float, float]) -> list[tuple]:
    """[(layer, kind, points (K, 3), indices, rgba)] of `location`'s map within `box`, layers in `LAYER_STYLE`
    order, empty layers left out. Needs the conversion's `map/` datasets (`Dataset.map`)."""
    layers = dataset.map(location)
    patch = shapely.box(*box)
    out = []
    for name, kind, rgba, z_m in LAYER_STYLE:
        source = layers.parts[name] if name == "drivable_area" else layers.layers[name]
        if not len(source.geometry):
            continue
        hits = source.geometry[np.sort(source.tree.query(patch, predicate="intersects"))]
        clipped = shapely.clip_by_rect(hits, *box) if len(hits) else hits
        points, indices = (triangles if kind == "triangles" else segments)(clipped, z_m)
        if len(indices):
            out.append((name, kind, points, indices, rgba))
    return out
