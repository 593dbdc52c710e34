"""Which part of the map each annotation and each ego pose lies on (the map datasets joined to the boxes).

`annotation_surfaces(ds)`: one row per annotation with the token of the record of each polygon layer its box
centre lies in ('' where none; the devkit's `layers_on_point` per annotation, answered in one vectorised call
per location) and a `surface`, the first that applies of: ped_crossing, walkway, carpark_area, intersection
(a road segment with `is_intersection`), lane (a lane or lane connector), drivable_area (elsewhere on the road),
off_map. `ego_surfaces(ds)` is the same for the reference lidar's keyframe ego poses. The stats sections
summarise them: pedestrians on crossings vs walkways vs the road, ego time on intersections.
The map is read once per location (`Dataset.map`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import polars as pl

from nuparquet.map.layers import LOOKUP_POLYGON_LAYERS
from nuparquet.queries.frames import ego_motion
from nuparquet.queries.inputs import for_scene

if TYPE_CHECKING:
    from nuparquet.dataset import Dataset
    from nuparquet.queries.inputs import Scene

# The polygon layers (the devkit's non_geometric_polygon_layers) and lane connectors. `nuparquet.map.layers` is
# names only: the map queries (shapely) load when a map query runs, not with `nuparquet stats`.
LAYERS = LOOKUP_POLYGON_LAYERS
SURFACES = ("ped_crossing", "walkway", "carpark_area", "intersection", "lane", "drivable_area", "off_map")
SURFACE_CODES = {name: code for code, name in enumerate(SURFACES)}


def _surfaces(ds: Dataset, points: pl.DataFrame, *, tokens: bool = True) -> pl.DataFrame:
    """points (location, x_m, y_m, ...) -> the same rows with one token column per layer (unless `tokens` is
    False) and `surface`. The map answers record rows (`MapLayers.records_on_point`); tokens are gathered by
    polars, not built as Python strings."""
    locations = set(ds.scan("map/lane").select("location").unique().collect()["location"].to_list())
    intersections = (ds.scan("map/road_segment").filter(pl.col("is_intersection")).select("token").unique()
                     .collect()["token"])
    parts = []
    for (location,), rows in points.group_by(["location"], maintain_order=True):
        if location in locations:
            m = ds.map(location)
            found = m.records_on_point(rows["x_m"].to_numpy(), rows["y_m"].to_numpy(), LAYERS)
            names = {layer: pl.Series(m.layers[layer].tokens.tolist(), dtype=pl.String) for layer in LAYERS}
            intersection = names["road_segment"].is_in(intersections.implode()).to_numpy()
        else:  # a log whose location has no map file
            found = {layer: np.full(rows.height, -1, dtype=np.int64) for layer in LAYERS}
            names = {layer: pl.Series([], dtype=pl.String) for layer in LAYERS}
            intersection = np.zeros(0, dtype=bool)
        on = {layer: found[layer] >= 0 for layer in LAYERS}
        segment = found["road_segment"]
        at_intersection = on["road_segment"] & intersection[np.where(on["road_segment"], segment, 0)] \
            if len(intersection) else np.zeros(rows.height, dtype=bool)
        surface = np.select([on["ped_crossing"], on["walkway"], on["carpark_area"], at_intersection,
                             on["lane"] | on["lane_connector"], on["drivable_area"]],
                            [SURFACE_CODES[s] for s in SURFACES[:-1]], SURFACE_CODES["off_map"])
        columns = [pl.Series("surface", surface, pl.UInt8)]
        if tokens:
            columns += [_tokens(names[layer], found[layer]).alias(layer) for layer in LAYERS]
        parts.append(rows.with_columns(columns))
    if parts:
        out = pl.concat(parts)
    else:
        out = points.with_columns([pl.lit(0, pl.UInt8).alias("surface")]
                                  + ([pl.lit("", pl.String).alias(layer) for layer in LAYERS] if tokens else []))
    surface = pl.col("surface").replace_strict(list(SURFACE_CODES.values()), list(SURFACE_CODES), return_dtype=pl.String)
    ordered = [c for c in out.columns if c != "surface"] + ["surface"]
    return out.with_columns(surface.alias("surface")).select(ordered)


def _tokens(names: pl.Series, rows: np.ndarray) -> pl.Series:
    """The tokens at record `rows` (-1: none, '')."""
    if not len(names):
        return pl.Series([""] * len(rows), dtype=pl.String)
    none = np.flatnonzero(rows < 0)
    gathered = names.gather(np.where(rows < 0, 0, rows))
    return gathered.scatter(none, "") if len(none) else gathered


def annotation_surfaces(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """``token, scene_name, location, category_name, x_m, y_m``, a token column per polygon layer, ``surface``."""
    return _annotation_surfaces(ds, scene).sort("scene_name", "token").lazy()


def _annotation_surfaces(ds: Dataset, scene: Scene, *, tokens: bool = True) -> pl.DataFrame:
    """`annotation_surfaces` unsorted; without `tokens`, only category_name, location, x_m, y_m and surface."""
    boxes = (for_scene(ds.scan("annotations"), scene)
             .select(*(["token", "scene_name"] if tokens else []), pl.col("log_location").cast(pl.String).alias("location"),
                     pl.col("category_name").cast(pl.String), pl.col("translation").arr.get(0).alias("x_m"),
                     pl.col("translation").arr.get(1).alias("y_m"))
             .collect())
    return _surfaces(ds, boxes, tokens=tokens)


def ego_surfaces(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """``scene_name, timestamp, location, x_m, y_m``, a token column per polygon layer, ``surface`` for the
    reference lidar's keyframe ego poses."""
    scenes = ds.scan("scenes").select(pl.col("name").alias("scene_name"), pl.col("log_location").alias("location"))
    poses = (ego_motion(ds, scene=scene).select("scene_name", "timestamp", "x_m", "y_m")
             .join(scenes, on="scene_name", how="left").collect())
    return _surfaces(ds, poses).sort("scene_name", "timestamp").lazy()


def surfaces_by_category(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """Annotations per category and surface: ``category_name``, one count column per surface, ``total``."""
    # the counts need neither the token columns nor an order
    counts = (_annotation_surfaces(ds, scene, tokens=False).group_by("category_name", "surface")
              .agg(pl.len().alias("n")))
    wide = counts.pivot(on="surface", index="category_name", values="n").fill_null(0)
    wide = wide.with_columns(pl.lit(0, pl.UInt32).alias(s) for s in SURFACES if s not in wide.columns)
    return (wide.select("category_name", *[pl.col(s).cast(pl.Int64) for s in SURFACES])
            .with_columns(pl.sum_horizontal(*SURFACES).alias("total")).sort("category_name").lazy())


def ego_time_on_surfaces(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """Per scene: keyframes, and the share of the reference-lidar keyframes on each surface
    (``share_<surface>``; × the scene's duration ≈ time spent there)."""
    poses = ego_surfaces(ds, scene=scene)
    return (poses.group_by("scene_name").agg(
        pl.len().alias("keyframes"),
        *[(pl.col("surface") == s).mean().alias(f"share_{s}") for s in SURFACES])
        .sort("scene_name"))
