"""Canned queries over `frames`: ego motion (from the reference lidar's keyframes) and channel rates."""

from __future__ import annotations

from typing import TYPE_CHECKING

import polars as pl

from nuparquet.channels import DEFAULT_REFERENCE_LIDAR
from nuparquet.queries.inputs import US_PER_S, for_scene, group_keys, lazy_of

if TYPE_CHECKING:
    from nuparquet.queries.inputs import Scene, Source


def _channel_or_reference(source, channel: str | None) -> str | None:
    """`channel`, else the reference lidar a Dataset records (None: find it in the frames themselves)."""
    if channel is not None or not hasattr(source, "channels"):
        return channel
    return source.channels.get("reference_lidar") or ""


def _of_channel(lf: pl.LazyFrame, channel: str | None) -> pl.LazyFrame:
    """Rows of `channel`; for None, of the reference lidar among the rows' own channels (`channels.reference_lidar`:
    its default channel when present, else the first lidar by name), found lazily."""
    name = pl.col("channel").cast(pl.String)
    if channel is not None:
        return lf.filter(name == channel)
    lidars = lf.filter(pl.col("modality").cast(pl.String) == "lidar").select(name.unique())
    reference = lidars.select(
        pl.when((pl.col("channel") == DEFAULT_REFERENCE_LIDAR).any())
        .then(pl.lit(DEFAULT_REFERENCE_LIDAR)).otherwise(pl.col("channel").min()).alias("channel"))
    return lf.with_columns(name).join(reference, on="channel", how="semi")


def ego_motion(frames: Source, *, channel: str | None = None, scene: Scene = None) -> pl.LazyFrame:
    """How fast does the ego vehicle drive and accelerate over each scene?

    From the ego poses of the keyframes of `channel` (default: the reference lidar, `Dataset.channels`, one
    keyframe per sample), in time order per scene:
    ``timestamp``, ``time_s`` since the scene's first such keyframe, ego position ``x_m, y_m, z_m`` (global),
    ``step_m`` = 3D distance from the previous keyframe's position, ``speed_mps`` = ``step_m`` / time since
    that keyframe (both null on the first),
    and ``accel_mps2`` = change of ``speed_mps`` / time between the midpoints of the two intervals (null on
    the first two).
    """
    lf = for_scene(lazy_of(frames, "frames"), scene)
    dt_s = pl.col("timestamp").diff().over("scene_name") / US_PER_S
    step_m = (pl.col("x_m").diff() ** 2 + pl.col("y_m").diff() ** 2 + pl.col("z_m").diff() ** 2).sqrt()
    return (
        _of_channel(lf.filter(pl.col("is_key_frame")), _channel_or_reference(frames, channel))
        .select("scene_name", "timestamp",
                *(pl.col("ego_translation").arr.get(i).alias(axis) for i, axis in enumerate(("x_m", "y_m", "z_m"))))
        .sort("scene_name", "timestamp")
        .with_columns(
            ((pl.col("timestamp") - pl.col("timestamp").min().over("scene_name")) / US_PER_S).alias("time_s"),
            dt_s.alias("dt_s"),
            step_m.over("scene_name").alias("step_m"),
        )
        .with_columns((pl.col("step_m") / pl.col("dt_s")).alias("speed_mps"))
        .with_columns(
            (pl.col("speed_mps").diff() / ((pl.col("dt_s") + pl.col("dt_s").shift(1)) / 2))
            .over("scene_name").alias("accel_mps2"))
        .select("scene_name", "timestamp", "time_s", "x_m", "y_m", "z_m", "step_m", "speed_mps", "accel_mps2")
    )


def ego_speed_summary(frames: Source, *, channel: str | None = None, scene: Scene = None) -> pl.LazyFrame:
    """How far and how fast did the ego vehicle drive in each scene? (A summary of `ego_motion`.)

    One row per scene: ``keyframes``, ``duration_s``, ``distance_m`` (sum of the steps between keyframes),
    ``mean_speed_mps`` = distance / duration, ``max_speed_mps``, ``max_abs_accel_mps2``.
    """
    return (
        ego_motion(frames, channel=channel, scene=scene)
        .group_by("scene_name")
        .agg(pl.len().cast(pl.Int64).alias("keyframes"), pl.col("time_s").max().alias("duration_s"),
             pl.col("step_m").sum().alias("distance_m"), pl.col("speed_mps").max().alias("max_speed_mps"),
             pl.col("accel_mps2").abs().max().alias("max_abs_accel_mps2"))
        .with_columns((pl.col("distance_m") / pl.col("duration_s")).alias("mean_speed_mps"))
        .select("scene_name", "keyframes", "duration_s", "distance_m", "mean_speed_mps", "max_speed_mps",
                "max_abs_accel_mps2")
        .sort("scene_name")
    )


def channel_rates(frames: Source, *, by_scene: bool = False, scene: Scene = None) -> pl.LazyFrame:
    """How many keyframes and sweeps does each sensor channel record, and at what rate?

    One row per channel (per scene and channel with ``by_scene=True``): ``modality``, ``num_frames``,
    ``num_keyframes``, ``num_sweeps``, and rates measured from the timestamps: ``frame_hz`` = frame intervals /
    time spanned (summed over scenes: a channel's first and last frame of each scene bound its span), and
    ``keyframe_hz`` the same over keyframes only. Null where a scene has fewer than two frames.
    """
    lf = for_scene(lazy_of(frames, "frames"), scene)
    key_ts = pl.col("timestamp").filter(pl.col("is_key_frame"))
    counts = (
        lf.select("scene_name", pl.col("channel").cast(pl.String), pl.col("modality").cast(pl.String),
                  "timestamp", "is_key_frame")
        .group_by("scene_name", "channel")
        .agg(
            pl.col("modality").first(),
            pl.len().cast(pl.Int64).alias("num_frames"),
            pl.col("is_key_frame").sum().cast(pl.Int64).alias("num_keyframes"),
            (pl.col("timestamp").max() - pl.col("timestamp").min()).alias("span_us"),
            (key_ts.max() - key_ts.min()).fill_null(0).alias("key_span_us"),
        )
        .with_columns((pl.col("num_frames") - 1).alias("frame_intervals"),
                      (pl.col("num_keyframes") - 1).clip(lower_bound=0).alias("key_intervals"))
    )
    if not by_scene:  # intervals and spans add up over scenes; the gaps between scenes are not time spanned
        counts = counts.group_by("channel").agg(
            pl.col("modality").first(),
            pl.col("num_frames", "num_keyframes", "span_us", "key_span_us", "frame_intervals", "key_intervals").sum())

    def rate(intervals: str, span: str) -> pl.Expr:
        return pl.when(pl.col(span) > 0).then(pl.col(intervals) * US_PER_S / pl.col(span)).otherwise(None)

    return (
        counts.with_columns(
            (pl.col("num_frames") - pl.col("num_keyframes")).alias("num_sweeps"),
            rate("frame_intervals", "span_us").alias("frame_hz"),
            rate("key_intervals", "key_span_us").alias("keyframe_hz"),
        )
        .select(*group_keys(by_scene, "channel"), "modality", "num_frames", "num_keyframes", "num_sweeps",
                "frame_hz", "keyframe_hz")
        .sort(group_keys(by_scene, "channel"))
    )
