"""Canned queries over `instances` and `scenes`: track statistics and the scene list."""

from __future__ import annotations

from typing import TYPE_CHECKING

import polars as pl

from nuparquet.queries.inputs import US_PER_S, for_scene, group_keys, lazy_of, second_of

if TYPE_CHECKING:
    from nuparquet.queries.inputs import Scene, Source


def track_stats(instances: Source, *, by_scene: bool = False, scene: Scene = None) -> pl.LazyFrame:
    """How long are the tracks (instances) of each category, in annotations, seconds and metres?

    One row per category (per scene and category with ``by_scene=True``; an instance belongs to the scene of
    its first annotation): ``num_tracks``; mean / median / max of ``nbr_annotations`` (``annotations_*``),
    of the duration last minus first annotation timestamp (``duration_s_*``) and of ``track_length_m``
    (path length of the box centres, ``length_m_*``).
    """
    lf = for_scene(lazy_of(instances, "instances"), scene)
    duration_s = (pl.col("last_timestamp") - pl.col("first_timestamp")) / US_PER_S

    def mmm(expr: pl.Expr, name: str) -> list[pl.Expr]:
        return [expr.mean().alias(f"{name}_mean"), expr.median().alias(f"{name}_median"),
                expr.max().alias(f"{name}_max")]

    return (
        lf.with_columns(pl.col("category_name").cast(pl.String))
        .group_by(group_keys(by_scene, "category_name"))
        .agg(pl.len().cast(pl.Int64).alias("num_tracks"), *mmm(pl.col("nbr_annotations"), "annotations"),
             *mmm(duration_s, "duration_s"), *mmm(pl.col("track_length_m"), "length_m"))
        .sort(group_keys(by_scene, "category_name"))
    )



def scene_summary(scenes: Source, annotations: Source | None = None, *, scene: Scene = None) -> pl.LazyFrame:
    """What does each scene hold? (`NuScenes.list_scenes()`, and more.)

    One row per scene, sorted by start time as list_scenes: ``name``, ``description``, ``start_utc`` (first
    sample time), ``date_captured``, ``duration_s``, ``log_location``, ``vehicle``, ``nbr_samples``,
    ``num_annotations`` (all samples), ``num_annotations_list_scenes`` (the ``#anns`` list_scenes prints: it
    leaves out the annotations of the scene's last sample), ``num_instances``, ``ego_distance_m``.
    Needs the scenes and annotations datasets.
    """
    scenes_lf = for_scene(lazy_of(scenes, "scenes"), scene, column="name")
    annotations_lf = for_scene(second_of(scenes, annotations, "annotations"), scene)
    last_sample = scenes_lf.select(pl.col("token").alias("scene_token"), "last_sample_token")
    listed = (
        annotations_lf.select("scene_token", "sample_token")
        .join(last_sample, on="scene_token", how="left")
        .filter(pl.col("sample_token") != pl.col("last_sample_token"))
        .group_by("scene_token")
        .agg(pl.len().cast(pl.Int64).alias("num_annotations_list_scenes"))
    )
    return (
        scenes_lf.join(listed, left_on="token", right_on="scene_token", how="left")
        .select(
            "name", "description",
            pl.from_epoch("first_timestamp", time_unit="us").dt.replace_time_zone("UTC").alias("start_utc"),
            "date_captured", "duration_s", "log_location", "vehicle", "nbr_samples", "num_annotations",
            pl.col("num_annotations_list_scenes").fill_null(0), "num_instances", "ego_distance_m",
            "first_timestamp",
        )
        .sort("first_timestamp", "name")
        .drop("first_timestamp")
    )
