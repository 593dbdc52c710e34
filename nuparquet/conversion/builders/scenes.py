"""`scenes/`: one row per scene with its log, time span, annotation counts, ego path length and split."""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.columns import to_numpy
from nuparquet.conversion.builders.common import declared_fields, reference_poses
from nuparquet.conversion import lookups
from nuparquet.conversion.lookups import as_int
from nuparquet.splits import known_split
from nuparquet.conversion.builder import BuildContext, Builder


def path_lengths(df: pl.DataFrame, group: str, order: str, position: str) -> pl.DataFrame:
    """Sum of 3D distances between consecutive positions of each group, in `order`: {group, _step}."""
    ordered = df.select(group, order, position).sort(group, order)
    xyz = to_numpy(ordered[position], (3,))
    groups = ordered[group].to_numpy()
    step = np.zeros(len(xyz))
    if len(xyz) > 1:
        same = groups[1:] == groups[:-1]
        step[1:] = np.where(same, np.linalg.norm(np.diff(xyz, axis=0), axis=1), 0.0)
    return ordered.select(group).with_columns(_step=pl.Series(step)).group_by(group).agg(pl.col("_step").sum())


def build_scenes(tables: dict[str, pl.DataFrame], references: pl.DataFrame, counts: pl.DataFrame,
                 source_version: str, family: str = "nuscenes") -> pl.DataFrame:
    """One row per scene. `counts`: scene_token -> num_annotations, num_instances over all annotations."""
    sample_ts = as_int(tables["sample"], "timestamp").select("token", "timestamp")
    ego_path = path_lengths(references, "scene_name", "timestamp", "ego_translation").rename(
        {"_step": "ego_distance_m"})
    scenes = (
        declared_fields(tables["scene"], "scene")
        .join(lookups.log_table(tables).select(pl.col("token").alias("log_token"), "logfile", "vehicle", "date_captured",
                              pl.col("location").alias("log_location")), on="log_token", how="left")
        .join(sample_ts.rename({"token": "first_sample_token", "timestamp": "first_timestamp"}),
              on="first_sample_token", how="left")
        .join(sample_ts.rename({"token": "last_sample_token", "timestamp": "last_timestamp"}),
              on="last_sample_token", how="left")
        .join(counts, left_on="token", right_on="scene_token", how="left")
        .join(ego_path, left_on="name", right_on="scene_name", how="left")
        .with_columns(
            duration_s=(pl.col("last_timestamp") - pl.col("first_timestamp")) / 1e6,
            num_annotations=pl.col("num_annotations").fill_null(0),
            num_instances=pl.col("num_instances").fill_null(0),
            ego_distance_m=pl.col("ego_distance_m").fill_null(0.0),
        )
        .sort("name", "token")
    )
    return scenes.with_columns(split=known_split(scenes["name"], source_version, family))


def scene_counts(annotations: pl.LazyFrame) -> pl.DataFrame:
    """scene_token -> num_annotations, num_instances."""
    return (annotations.group_by("scene_token")
            .agg(num_annotations=pl.len().cast(pl.UInt32), num_instances=pl.col("instance_token").n_unique().cast(pl.UInt32))
            .collect())


def build(ctx: BuildContext) -> pl.DataFrame:
    counts = scene_counts(ctx.dataset("annotations").select("scene_token", "instance_token"))
    return build_scenes(ctx.tables, reference_poses(ctx), counts, ctx.version, ctx.source_format)


BUILDER = Builder("scenes", build, scope="whole", schema="scenes", group_by=None, needs=("annotations",))
