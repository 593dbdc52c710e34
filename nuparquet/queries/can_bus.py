"""Canned queries over the CAN bus datasets (`can_bus/<message>`, converted when the dataroot has `can_bus/`).

Units: `vehicle_monitor.vehicle_speed` is km/h in the files (shown here as m/s), `pose.vel` is m/s in the
vehicle frame (x forward), `steeranglefeedback.value` is the steering wheel angle in radians,
`vehicle_monitor.yaw_rate` deg/s, `brake` and `throttle` the pedal positions as integers (0 = released).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import polars as pl

from nuparquet.queries.frames import ego_motion
from nuparquet.queries.inputs import US_PER_S, for_scene

if TYPE_CHECKING:
    from nuparquet.dataset import Dataset
    from nuparquet.queries.inputs import Scene

KMH_PER_MPS = 3.6


def _seconds(lf: pl.LazyFrame, start: pl.LazyFrame) -> pl.LazyFrame:
    """`time_s` since the scene's first sample (`start`: scene_name, t0)."""
    return lf.join(start, on="scene_name", how="left").with_columns(
        ((pl.col("utime") - pl.col("t0")) / US_PER_S).alias("time_s")).drop("t0")


def _scene_start(ds: Dataset) -> pl.LazyFrame:
    return ds.scan("scenes").select(pl.col("name").alias("scene_name"), pl.col("first_timestamp").alias("t0"))


def speed_over_time(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """Speed from three sources, in one long table: ``scene_name, source, time_s, speed_mps`` with `source`
    "vehicle_monitor" (its `vehicle_speed`, 2 Hz; the wheel speeds are zoe_veh_info's), "pose" (CAN pose |vel|,
    50 Hz) and "ego_pose" (from the reference
    lidar keyframe poses, 2 Hz, `queries.ego_motion`); time since the scene's first sample."""
    start = _scene_start(ds)
    monitor = for_scene(ds.scan("can_bus/vehicle_monitor"), scene)
    pose = for_scene(ds.scan("can_bus/pose"), scene)
    vel = pl.col("vel")
    parts = [
        _seconds(monitor.select("scene_name", "utime", (pl.col("vehicle_speed") / KMH_PER_MPS).alias("speed_mps")), start)
        .with_columns(pl.lit("vehicle_monitor").alias("source")),
        _seconds(pose.select("scene_name", "utime", (vel.arr.get(0) ** 2 + vel.arr.get(1) ** 2 + vel.arr.get(2) ** 2)
                             .sqrt().alias("speed_mps")), start).with_columns(pl.lit("pose").alias("source")),
        ego_motion(ds, scene=scene).join(start, on="scene_name", how="left").select(
            "scene_name", pl.col("timestamp").alias("utime"), "speed_mps",
            ((pl.col("timestamp") - pl.col("t0")) / US_PER_S).alias("time_s"), pl.lit("ego_pose").alias("source")),
    ]
    return (pl.concat([p.select("scene_name", "source", "time_s", "speed_mps") for p in parts])
            .sort("scene_name", "source", "time_s"))


def can_speed(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """Per scene: mean and max speed from CAN (vehicle_monitor vehicle_speed, pose |vel|) next to the ego-pose speed
    (reference lidar keyframes), m/s; `ego_vs_can_mps` = mean ego-pose speed - mean vehicle_monitor speed."""
    series = speed_over_time(ds, scene=scene).drop_nulls("speed_mps")
    wide = series.group_by("scene_name", "source").agg(
        pl.col("speed_mps").mean().alias("mean"), pl.col("speed_mps").max().alias("max"))
    out = None
    for source in ("vehicle_monitor", "pose", "ego_pose"):
        part = wide.filter(pl.col("source") == source).select(
            "scene_name", pl.col("mean").alias(f"{source}_mean_mps"), pl.col("max").alias(f"{source}_max_mps"))
        out = part if out is None else out.join(part, on="scene_name", how="full", coalesce=True)
    return (out.with_columns((pl.col("ego_pose_mean_mps") - pl.col("vehicle_monitor_mean_mps")).alias("ego_vs_can_mps"))
            .sort("scene_name"))


def steering_over_time(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """Steering wheel angle (steeranglefeedback, rad, 100 Hz) and yaw rate (pose rotation_rate z, rad/s, 50 Hz)
    over time: ``scene_name, source, time_s, value`` with `source` "steering_rad" or "yaw_rate_radps"."""
    start = _scene_start(ds)
    steer = _seconds(for_scene(ds.scan("can_bus/steeranglefeedback"), scene).select(
        "scene_name", "utime", pl.col("value")), start).with_columns(pl.lit("steering_rad").alias("source"))
    yaw = _seconds(for_scene(ds.scan("can_bus/pose"), scene).select(
        "scene_name", "utime", pl.col("rotation_rate").arr.get(2).alias("value")), start).with_columns(
        pl.lit("yaw_rate_radps").alias("source"))
    return pl.concat([p.select("scene_name", "source", "time_s", "value") for p in (steer, yaw)]).sort(
        "scene_name", "source", "time_s")


def brake_throttle(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """Per scene, from vehicle_monitor (2 Hz): messages, share of them with the brake pressed (`brake` > 0) and
    with throttle (> 0), mean and max of each pedal."""
    monitor = for_scene(ds.scan("can_bus/vehicle_monitor"), scene)
    return (monitor.group_by("scene_name").agg(
        pl.len().alias("messages"),
        (pl.col("brake") > 0).mean().alias("braking_share"), pl.col("brake").mean().alias("brake_mean"),
        pl.col("brake").max().alias("brake_max"),
        (pl.col("throttle") > 0).mean().alias("throttle_share"), pl.col("throttle").mean().alias("throttle_mean"),
        pl.col("throttle").max().alias("throttle_max"))
        .sort("scene_name"))
