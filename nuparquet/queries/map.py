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


def _surfaces(ds: Dataset, points: pl.DataFrame) -> pl.DataFrame:
    """points (location, x_m, y_m, ...) -> the same rows with one token column per layer and `surface`."""
    locations = set(ds.scan("map/lane").select("location").unique().collect()["location"].to_list())
    intersections = set(ds.scan("map/road_segment").filter(pl.col("is_intersection")).select("token")
                        .collect()["token"].to_list())
    parts = []
    for (location,), rows in points.group_by(["location"], maintain_order=True):
        if location in locations:
            found = ds.map(location).layers_on_point(rows["x_m"].to_numpy(), rows["y_m"].to_numpy(), LAYERS)
        else:  # a log whose location has no map file
            found = {layer: np.full(rows.height, "", dtype=object) for layer in LAYERS}
        parts.append(rows.with_columns(pl.Series(layer, found[layer].tolist(), pl.String) for layer in LAYERS))
    out = pl.concat(parts) if parts else points.with_columns(pl.lit("", pl.String).alias(layer) for layer in LAYERS)
    on = lambda layer: pl.col(layer) != ""  # noqa: E731
    surface = (pl.when(on("ped_crossing")).then(pl.lit("ped_crossing"))
               .when(on("walkway")).then(pl.lit("walkway"))
               .when(on("carpark_area")).then(pl.lit("carpark_area"))
               .when(pl.col("road_segment").is_in(list(intersections))).then(pl.lit("intersection"))
               .when(on("lane") | on("lane_connector")).then(pl.lit("lane"))
               .when(on("drivable_area")).then(pl.lit("drivable_area"))
               .otherwise(pl.lit("off_map")))
    return out.with_columns(surface.alias("surface"))


def annotation_surfaces(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """``token, scene_name, location, category_name, x_m, y_m``, a token column per polygon layer, ``surface``."""
    boxes = (for_scene(ds.scan("annotations"), scene)
             .select("token", "scene_name", pl.col("log_location").cast(pl.String).alias("location"),
                     pl.col("category_name").cast(pl.String), pl.col("translation").arr.get(0).alias("x_m"),
                     pl.col("translation").arr.get(1).alias("y_m"))
             .collect())
    return _surfaces(ds, boxes).sort("scene_name", "token").lazy()


def ego_surfaces(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """``scene_name, timestamp, location, x_m, y_m``, a token column per polygon layer, ``surface`` for the
    reference lidar's keyframe ego poses."""
    scenes = ds.scan("scenes").select(pl.col("name").alias("scene_name"), pl.col("log_location").alias("location"))
    poses = (ego_motion(ds, scene=scene).select("scene_name", "timestamp", "x_m", "y_m")
             .join(scenes, on="scene_name", how="left").collect())
    return _surfaces(ds, poses).sort("scene_name", "timestamp").lazy()


def surfaces_by_category(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """Annotations per category and surface: ``category_name``, one count column per surface, ``total``."""
    counts = annotation_surfaces(ds, scene=scene).group_by("category_name", "surface").agg(pl.len().alias("n")).collect()
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
