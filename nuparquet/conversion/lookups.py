"""Lookups several builders share, computed once per conversion from the typed source tables: which scene
and batch each sample belongs to, and the reference-lidar pose that stands for "the ego vehicle at a sample"."""

from __future__ import annotations

import polars as pl

from nuparquet.channels import reference_lidar


def as_int(df: pl.DataFrame, *columns: str) -> pl.DataFrame:
    """Integer fields the source stored as JSON floats (kept as float64 in tables/) as int64 for the joins;
    NaN, infinities (Lyft writes `"width": NaN` for lidar rows) and values beyond int64 become null."""
    in_range = lambda c: pl.col(c).is_finite() & (pl.col(c).abs() < 2.0**63)  # noqa: E731
    return df.with_columns([pl.when(in_range(c)).then(pl.col(c).round(0)).cast(pl.Int64).alias(c)
                            for c in columns if df.schema[c].is_float()])


def sample_lookup(tables: dict[str, pl.DataFrame]) -> pl.DataFrame:
    """sample_token -> scene_token, scene_name, log_location, sample_timestamp (one row per sample). `log_location` is
    categorical: a location string is held once, however many rows it reaches (issue 27: a 40 MB location)."""
    return (
        as_int(tables["sample"], "timestamp").select(pl.col("token").alias("sample_token"), "scene_token",
                                                pl.col("timestamp").alias("sample_timestamp"))
        .join(tables["scene"].select(pl.col("token").alias("scene_token"), pl.col("name").alias("scene_name"), "log_token"),
              on="scene_token", how="left")
        .join(log_table(tables).select(pl.col("token").alias("log_token"),
                                       pl.col("location").cast(pl.Categorical).alias("log_location")),
              on="log_token", how="left")
        .select("sample_token", "scene_token", "scene_name", "log_location", "sample_timestamp")
    )


def log_table(tables: dict[str, pl.DataFrame]) -> pl.DataFrame:
    """The `log` table, or an empty one for a format without logs (TruckScenes: every log column joins null)."""
    if "log" in tables:
        return tables["log"]
    return pl.DataFrame(schema={name: pl.String for name in ("token", "logfile", "vehicle", "date_captured", "location")})


def scene_batches(tables: dict[str, pl.DataFrame], samples: pl.DataFrame, scenes_per_batch: int) -> pl.DataFrame:
    """sample_token -> `_batch`: scenes in name order, `scenes_per_batch` to a batch."""
    order = tables["scene"].select(pl.col("token").alias("scene_token"), "name").sort("name", "scene_token")
    order = order.with_columns(_batch=(pl.int_range(pl.len()) // scenes_per_batch).cast(pl.Int32))
    return samples.select("sample_token", "scene_token").join(order, on="scene_token", how="left").select(
        "sample_token", "_batch")


def reference_channel(tables: dict[str, pl.DataFrame]) -> str | None:
    """The reference lidar of the dataset (`nuparquet.channels.reference_lidar`)."""
    return reference_lidar(tables["sensor"]["channel"].to_list(), tables["sensor"]["modality"].to_list())


def reference_poses(tables: dict[str, pl.DataFrame], samples: pl.DataFrame) -> pl.DataFrame:
    """Per sample: timestamp and ego translation of its reference-lidar keyframe."""
    channel = reference_channel(tables)
    if channel is None:  # a layout without lidar: no sample has a reference pose
        return pl.DataFrame(schema={"sample_token": pl.String, "scene_name": pl.String, "timestamp": pl.Int64,
                                    "ego_translation": pl.Array(pl.Float64, 3)})
    sensor_tokens = tables["sensor"].filter(pl.col("channel") == channel)["token"]
    calibrations = tables["calibrated_sensor"].filter(pl.col("sensor_token").is_in(sensor_tokens.implode()))["token"]
    return (
        as_int(tables["sample_data"], "timestamp").lazy()
        .filter(pl.col("is_key_frame") & pl.col("calibrated_sensor_token").is_in(calibrations.implode()))
        .select("sample_token", "timestamp", "ego_pose_token")
        .join(tables["ego_pose"].lazy().select(pl.col("token").alias("ego_pose_token"), pl.col("translation").alias("ego_translation")),
              on="ego_pose_token", how="left")
        .join(samples.lazy().select("sample_token", "scene_name"), on="sample_token", how="left")
        .unique("sample_token", keep="first")
        .select("sample_token", "scene_name", "timestamp", "ego_translation")
        .collect()
    )
