"""Canned queries over `annotations`: categories, attributes, visibility, points per box, distances."""

from __future__ import annotations

from typing import TYPE_CHECKING

import polars as pl

from nuparquet.queries.inputs import QUANTILES, for_scene, group_keys, lazy_of, mean_std

if TYPE_CHECKING:
    from nuparquet.queries.inputs import Scene, Source


def class_distribution(annotations: Source, *, by_scene: bool = False, scene: Scene = None) -> pl.LazyFrame:
    """How many annotations and instances does each category have, and how big are its boxes?

    One row per category (per scene and category with ``by_scene=True``): ``num_annotations``,
    ``num_instances`` (distinct instance tokens among those annotations) and the mean and population standard
    deviation of ``width``, ``length``, ``height`` (metres, from ``size = [w, l, h]``) and ``lw_aspect`` =
    length / width: the numbers `NuScenes.list_categories()` prints, sorted by category name like it.
    """
    lf = for_scene(lazy_of(annotations, "annotations"), scene)
    width, length, height = (pl.col("size").arr.get(i) for i in range(3))
    return (
        lf.with_columns(pl.col("category_name").cast(pl.String))
        .group_by(group_keys(by_scene, "category_name"))
        .agg(
            pl.len().alias("num_annotations"),
            pl.col("instance_token").n_unique().alias("num_instances"),
            *mean_std(width, "width"), *mean_std(length, "length"), *mean_std(height, "height"),
            *mean_std(length / width, "lw_aspect"),
        )
        .with_columns(pl.col("num_annotations", "num_instances").cast(pl.Int64))
        .sort(group_keys(by_scene, "category_name"))
    )


def attribute_counts(annotations: Source, *, by_category: bool = False, scene: Scene = None) -> pl.LazyFrame:
    """How often is each attribute given to an annotation? (`NuScenes.list_attributes()`.)

    One row per attribute name (per category and attribute with ``by_category=True``): ``count`` = the number
    of annotations carrying it; an annotation with two attributes counts once for each, one without any
    counts nowhere. Sorted by attribute name.
    """
    lf = for_scene(lazy_of(annotations, "annotations"), scene)
    keys = (["category_name"] if by_category else []) + ["attribute_name"]
    return (
        lf.select(pl.col("category_name").cast(pl.String), pl.col("attribute_names").alias("attribute_name"))
        .explode("attribute_name")
        .filter(pl.col("attribute_name").is_not_null())
        .group_by(keys)
        .agg(pl.len().cast(pl.Int64).alias("count"))
        .sort(keys)
    )


def visibility_by_category(annotations: Source, *, scene: Scene = None) -> pl.LazyFrame:
    """How visible are the boxes of each category in the cameras?

    One row per (category, ``visibility_level``: the visibility bin 1..4 of the source, null if the token is
    not an integer): ``count`` of annotations and ``share`` of the category's annotations (0..1).
    """
    lf = for_scene(lazy_of(annotations, "annotations"), scene)
    return (
        lf.select(pl.col("category_name").cast(pl.String), "visibility_level")
        .group_by("category_name", "visibility_level")
        .agg(pl.len().cast(pl.Int64).alias("count"))
        .with_columns((pl.col("count") / pl.col("count").sum().over("category_name")).alias("share"))
        .sort("category_name", "visibility_level", nulls_last=True)
    )


def _point_stats(column: str, prefix: str) -> list[pl.Expr]:
    # Negative counts are sentinels, not data (Lyft Level 5 writes num_lidar_pts = -1 where it did not count):
    # they are left out of every statistic (num_boxes still counts the box).
    values = pl.when(pl.col(column) >= 0).then(pl.col(column))
    return [
        values.mean().alias(f"{prefix}_mean"),
        values.min().alias(f"{prefix}_min"),
        *(values.quantile(q, "linear").alias(f"{prefix}_p{round(q * 100):02d}") for q in QUANTILES),
        values.max().alias(f"{prefix}_max"),
        (values == 0).mean().alias(f"{prefix}_zero_share"),
    ]


def points_per_box(annotations: Source, *, scene: Scene = None) -> pl.LazyFrame:
    """How many lidar and radar points fall inside the boxes of each category?

    One row per category: ``num_boxes``; for ``lidar`` (``num_lidar_pts``) and ``radar`` (``num_radar_pts``)
    the mean, min, 5/25/50/75/95th percentiles (``lidar_p05`` ... ``lidar_p95``, linear interpolation as
    numpy.percentile), max, and ``*_zero_share``: the share of boxes with no point at all (0..1). Negative counts
    (sentinels such as Lyft's -1, "not counted") are left out of these statistics.
    """
    lf = for_scene(lazy_of(annotations, "annotations"), scene)
    return (
        lf.select(pl.col("category_name").cast(pl.String), "num_lidar_pts", "num_radar_pts")
        .group_by("category_name")
        .agg(pl.len().cast(pl.Int64).alias("num_boxes"),
             *_point_stats("num_lidar_pts", "lidar"), *_point_stats("num_radar_pts", "radar"))
        .sort("category_name")
    )


def distance_histogram(annotations: Source, *, bin_width_m: float = 10.0, scene: Scene = None) -> pl.LazyFrame:
    """How far from the ego vehicle are the boxes of each category?

    Histogram of ``distance_to_ego_m`` (xy distance from the box centre to the ego position of the sample's
    reference-lidar keyframe) in bins ``[bin_start_m, bin_end_m)`` of ``bin_width_m`` metres starting at 0: one
    row per category and non-empty bin with its ``count``. Annotations without a distance (no reference-lidar
    keyframe) are left out.
    """
    if not bin_width_m > 0:
        raise ValueError("bin_width_m must be positive")
    lf = for_scene(lazy_of(annotations, "annotations"), scene)
    bin_start = (pl.col("distance_to_ego_m") / bin_width_m).floor() * bin_width_m
    return (
        lf.select(pl.col("category_name").cast(pl.String), "distance_to_ego_m")
        .filter(pl.col("distance_to_ego_m").is_not_null())
        .group_by("category_name", bin_start.alias("bin_start_m"))
        .agg(pl.len().cast(pl.Int64).alias("count"))
        .select("category_name", "bin_start_m", (pl.col("bin_start_m") + bin_width_m).alias("bin_end_m"), "count")
        .sort("category_name", "bin_start_m")
    )
