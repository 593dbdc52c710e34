"""`frames/`: one row per sample_data with its pose, calibration, sensor, sample, scene, log and 4x4 transforms."""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet import geometry
from nuparquet.columns import to_numpy, to_series
from nuparquet.conversion.builders.common import declared_fields, samples
from nuparquet.conversion.lookups import as_int
from nuparquet.conversion.builder import BuildContext, Builder, SceneBatch


def build_frames(tables: dict[str, pl.DataFrame], sample_data: pl.DataFrame, samples: pl.DataFrame) -> pl.DataFrame:
    """One row per row of `sample_data` (a batch of scenes). `samples` is `lookups.sample_lookup(tables)`."""
    sample_data = as_int(declared_fields(sample_data, "sample_data"), "timestamp", "width", "height").with_columns(
        pl.col("width").fill_null(0), pl.col("height").fill_null(0))  # 0 for non-images, as nuScenes writes it
    frames = (
        sample_data.lazy()
        .join(tables["ego_pose"].lazy().select(
            pl.col("token").alias("ego_pose_token"), pl.col("translation").alias("ego_translation"),
            pl.col("rotation").alias("ego_rotation")), on="ego_pose_token", how="left")
        .join(tables["calibrated_sensor"].lazy().select(
            pl.col("token").alias("calibrated_sensor_token"), "sensor_token",
            pl.col("translation").alias("sensor_translation"), pl.col("rotation").alias("sensor_rotation"),
            "camera_intrinsic"), on="calibrated_sensor_token", how="left")
        # categorical: a sensor's words are held once, however many rows reach them (they sort as strings do)
        .join(tables["sensor"].lazy().select(pl.col("token").alias("sensor_token"), pl.col("channel", "modality")
                                             .cast(pl.Categorical)), on="sensor_token", how="left")
        .join(samples.lazy().drop("sample_timestamp"), on="sample_token", how="left")
        .with_columns(time_utc=pl.from_epoch("timestamp", time_unit="us").dt.replace_time_zone("UTC"))
        .sort("scene_name", "channel", "timestamp", "token")
        .collect()
    )
    global_from_ego = geometry.rigid_transforms(to_numpy(frames["ego_translation"], (3,)),
                                                to_numpy(frames["ego_rotation"], (4,)))
    ego_from_sensor = geometry.rigid_transforms(to_numpy(frames["sensor_translation"], (3,)),
                                                to_numpy(frames["sensor_rotation"], (4,)))
    # null, not NaN, where the ego pose or calibration is absent (only `--allow-dangling` lets such rows through)
    has_pose = frames["ego_translation"].is_not_null().to_numpy()
    has_calibration = frames["sensor_translation"].is_not_null().to_numpy()
    is_camera = frames["camera_intrinsic"].is_not_null().to_numpy()
    image_from_sensor = np.tile(np.eye(4), (frames.height, 1, 1))
    if is_camera.any():
        image_from_sensor[is_camera, :3, :3] = to_numpy(frames["camera_intrinsic"].filter(pl.Series(is_camera)), (3, 3))
    sensor_from_global = geometry.invert_rigid(ego_from_sensor) @ geometry.invert_rigid(global_from_ego)
    return frames.with_columns(
        to_series("global_from_ego", global_from_ego, valid=has_pose),
        to_series("ego_from_sensor", ego_from_sensor, valid=has_calibration),
        to_series("image_from_global", image_from_sensor @ sensor_from_global, valid=is_camera & has_pose),
    )


def build(ctx: BuildContext, batch: SceneBatch) -> pl.DataFrame:
    return build_frames(ctx.tables | {"ego_pose": batch.rows["ego_pose"]}, batch.rows["sample_data"], samples(ctx))


BUILDER = Builder("frames", build, schema="frames")
