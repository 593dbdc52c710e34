"""`instances/`: one row per instance (track) with its category, scene, first/last times and track length."""

from __future__ import annotations

import polars as pl

from nuparquet.conversion.builders.common import declared_fields
from nuparquet.conversion.builders.scenes import path_lengths
from nuparquet.conversion.builder import BuildContext, Builder


def build_instances(tables: dict[str, pl.DataFrame], annotation_times: pl.DataFrame, track_lengths: pl.DataFrame) -> pl.DataFrame:
    """One row per instance. `annotation_times`: token, scene_token, scene_name, timestamp of every
    annotation; `track_lengths`: path_lengths of the annotation centres per instance_token."""
    by_token = annotation_times.select("token", "scene_token", "scene_name", "timestamp")
    return (
        declared_fields(tables["instance"], "instance").with_row_index("file_index")
        .join(tables["category"].select(pl.col("token").alias("category_token"),
                                        pl.col("name").cast(pl.Categorical).alias("category_name")),
              on="category_token", how="left")
        .join(by_token.rename({"token": "first_annotation_token", "timestamp": "first_timestamp"}),
              on="first_annotation_token", how="left")
        .join(by_token.select(pl.col("token").alias("last_annotation_token"), pl.col("timestamp").alias("last_timestamp")),
              on="last_annotation_token", how="left")
        .join(track_lengths.rename({"_step": "track_length_m"}), left_on="token", right_on="instance_token", how="left")
        .with_columns(track_length_m=pl.col("track_length_m").fill_null(0.0))
        .sort("scene_name", "first_timestamp", "token")
    )


def build(ctx: BuildContext) -> pl.DataFrame:
    annotations = ctx.dataset("annotations").select(
        "token", "scene_token", "scene_name", "timestamp", "instance_token", "translation").collect()
    lengths = path_lengths(annotations, "instance_token", "timestamp", "translation")
    return build_instances(ctx.tables, annotations, lengths)


BUILDER = Builder("instances", build, scope="whole", schema="instances", group_by=None, needs=("annotations",))
