"""The denormalised datasets (frames, annotations, scenes, instances) built from the typed source tables.

Joins happen in polars; derived geometry (transforms, velocity, yaw, path lengths) in vectorised numpy.
Nothing here loops over records. Inputs are the polars frames of the source tables by name.

frames and annotations are built a batch of scenes at a time (`scene_batches`): at trainval scale the
whole frames table with its three 4x4 matrices would need several GB at once, while every join and
derivation here stays inside one scene (tracks and sensor chains never cross scenes).
"""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import polars as pl

from nuparquet import geometry

# devkit NuScenes.box_velocity's default: neighbours further apart than this (doubled for a centred
# difference) give NaN.
MAX_VELOCITY_TIME_DIFF_S = 1.5
# The keyframe sensor whose ego pose stands for "the ego vehicle at this sample" (as in the devkit).
REFERENCE_CHANNEL = "LIDAR_TOP"


def _as_int(df: pl.DataFrame, *columns: str) -> pl.DataFrame:
    return df.with_columns([pl.col(c).round(0).cast(pl.Int64) for c in columns if df.schema[c].is_float()])


def _vectors(series: pl.Series, width: int) -> np.ndarray:
    """A fixed-size-list column as an (N, width) float64 array (zero-copy when possible)."""
    return series.cast(pl.Array(pl.Float64, width)).to_numpy().reshape(-1, width)


def _matrix_column(values: np.ndarray) -> pl.Series:
    """(N, 4, 4) -> Array(Float64, 16), row-major."""
    return pl.Series(values.reshape(len(values), 16), dtype=pl.Array(pl.Float64, 16))


def build_frames(t: dict[str, pl.DataFrame], sample_data: pl.DataFrame, samples: pl.DataFrame) -> pl.DataFrame:
    """One row per row of `sample_data` (a batch of scenes) with its pose, calibration, sensor, sample,
    scene, log and 4x4 transforms. `samples` is `sample_lookup(t)`."""
    sample_data = _as_int(sample_data, "timestamp", "width", "height")
    frames = (
        sample_data.lazy()
        .join(t["ego_pose"].lazy().select(
            pl.col("token").alias("ego_pose_token"), pl.col("translation").alias("ego_translation"),
            pl.col("rotation").alias("ego_rotation")), on="ego_pose_token", how="left")
        .join(t["calibrated_sensor"].lazy().select(
            pl.col("token").alias("calibrated_sensor_token"), "sensor_token",
            pl.col("translation").alias("sensor_translation"), pl.col("rotation").alias("sensor_rotation"),
            "camera_intrinsic"), on="calibrated_sensor_token", how="left")
        .join(t["sensor"].lazy().select(pl.col("token").alias("sensor_token"), "channel", "modality"),
              on="sensor_token", how="left")
        .join(samples.lazy().drop("sample_timestamp"), on="sample_token", how="left")
        .with_columns(time_utc=pl.from_epoch("timestamp", time_unit="us").dt.replace_time_zone("UTC"))
        .sort("scene_name", "channel", "timestamp", "token")
        .collect()
    )
    global_from_ego = geometry.rigid_transforms(_vectors(frames["ego_translation"], 3), _vectors(frames["ego_rotation"], 4))
    ego_from_sensor = geometry.rigid_transforms(_vectors(frames["sensor_translation"], 3),
                                                _vectors(frames["sensor_rotation"], 4))
    is_camera = frames["camera_intrinsic"].is_not_null().to_numpy()
    image_from_sensor = np.tile(np.eye(4), (frames.height, 1, 1))
    if is_camera.any():
        intrinsics = frames["camera_intrinsic"].filter(frames["camera_intrinsic"].is_not_null())
        image_from_sensor[is_camera, :3, :3] = intrinsics.to_numpy().reshape(-1, 3, 3)
    sensor_from_global = geometry.invert_rigid(ego_from_sensor) @ geometry.invert_rigid(global_from_ego)
    image_from_global = _matrix_column(image_from_sensor @ sensor_from_global)
    return frames.with_columns(
        global_from_ego=_matrix_column(global_from_ego),
        ego_from_sensor=_matrix_column(ego_from_sensor),
        image_from_global=pl.when(pl.Series(is_camera)).then(image_from_global),
    )


def sample_lookup(t: dict[str, pl.DataFrame]) -> pl.DataFrame:
    """sample_token -> scene_token, scene_name, log_location, sample_timestamp (one row per sample)."""
    return (
        _as_int(t["sample"], "timestamp").select(pl.col("token").alias("sample_token"), "scene_token",
                                                 pl.col("timestamp").alias("sample_timestamp"))
        .join(t["scene"].select(pl.col("token").alias("scene_token"), pl.col("name").alias("scene_name"), "log_token"),
              on="scene_token", how="left")
        .join(t["log"].select(pl.col("token").alias("log_token"), pl.col("location").alias("log_location")),
              on="log_token", how="left")
        .select("sample_token", "scene_token", "scene_name", "log_location", "sample_timestamp")
    )


def scene_batches(t: dict[str, pl.DataFrame], samples: pl.DataFrame, scenes_per_batch: int) -> pl.DataFrame:
    """sample_token -> `_batch`: scenes in name order, `scenes_per_batch` to a batch."""
    order = t["scene"].select(pl.col("token").alias("scene_token"), "name").sort("name", "scene_token")
    order = order.with_columns(_batch=(pl.int_range(pl.len()) // scenes_per_batch).cast(pl.Int32))
    return samples.select("sample_token", "scene_token").join(order, on="scene_token", how="left").select(
        "sample_token", "_batch")


def reference_channel(t: dict[str, pl.DataFrame]) -> str | None:
    """LIDAR_TOP when the dataset has it, else the first lidar channel by name (other layouts)."""
    sensors = t["sensor"]
    if (sensors["channel"] == REFERENCE_CHANNEL).any():
        return REFERENCE_CHANNEL
    lidars = sensors.filter(pl.col("modality") == "lidar")["channel"].sort()
    return lidars[0] if len(lidars) else None


def reference_poses(t: dict[str, pl.DataFrame], samples: pl.DataFrame) -> pl.DataFrame:
    """Per sample: timestamp and ego translation of its reference-channel (LIDAR_TOP) keyframe."""
    channel = reference_channel(t)
    if channel is None:  # a layout without lidar: no sample has a reference pose
        return pl.DataFrame(schema={"sample_token": pl.String, "scene_name": pl.String, "timestamp": pl.Int64,
                                    "ego_translation": pl.Array(pl.Float64, 3)})
    sensor_tokens = t["sensor"].filter(pl.col("channel") == channel)["token"]
    calibrations = t["calibrated_sensor"].filter(pl.col("sensor_token").is_in(sensor_tokens.implode()))["token"]
    return (
        _as_int(t["sample_data"], "timestamp").lazy()
        .filter(pl.col("is_key_frame") & pl.col("calibrated_sensor_token").is_in(calibrations.implode()))
        .select("sample_token", "timestamp", "ego_pose_token")
        .join(t["ego_pose"].lazy().select(pl.col("token").alias("ego_pose_token"), pl.col("translation").alias("ego_translation")),
              on="ego_pose_token", how="left")
        .join(samples.lazy().select("sample_token", "scene_name"), on="sample_token", how="left")
        .unique("sample_token", keep="first")
        .select("sample_token", "scene_name", "timestamp", "ego_translation")
        .collect()
    )


def build_annotations(t: dict[str, pl.DataFrame], annotations: pl.DataFrame, samples: pl.DataFrame,
                      references: pl.DataFrame) -> pl.DataFrame:
    """One row per row of `annotations` (sample_annotation rows of a batch of scenes), joined and with
    velocity, yaw and distance to the ego vehicle. `references` is `reference_poses(t, samples)`."""
    names = dict(zip(t["attribute"]["token"].to_list(), t["attribute"]["name"].to_list()))  # a handful
    ann = annotations.with_columns(attribute_names=pl.col("attribute_tokens").list.eval(
        pl.element().replace_strict(names, return_dtype=pl.String)))
    ego = references.select("sample_token", pl.col("ego_translation").alias("_ego"))
    ann = (
        ann.lazy()
        .join(samples.lazy(), on="sample_token", how="left")
        .rename({"sample_timestamp": "timestamp"})
        .join(t["instance"].lazy().select(pl.col("token").alias("instance_token"), "category_token"),
              on="instance_token", how="left")
        .join(t["category"].lazy().select(pl.col("token").alias("category_token"), pl.col("name").alias("category_name")),
              on="category_token", how="left")
        .join(ego.lazy(), on="sample_token", how="left")
        .with_columns(visibility_level=pl.col("visibility_token").cast(pl.Int8, strict=False))
        .collect()
    )
    translation = _vectors(ann["translation"], 3)
    ann = ann.with_columns(
        velocity=pl.Series(_box_velocity(ann), dtype=pl.Array(pl.Float64, 3)),
        yaw=pl.Series(geometry.yaw_from_quaternions(_vectors(ann["rotation"], 4))),
        distance_to_ego_m=pl.Series(_xy_distance(translation, ann["_ego"])).fill_nan(None),
    )
    return ann.drop("_ego", "category_token").sort("scene_name", "timestamp", "instance_token", "token")


def _xy_distance(translation: np.ndarray, ego: pl.Series) -> np.ndarray:
    """xy distance of each box centre to its ego position; NaN where there is none."""
    present = ego.is_not_null().to_numpy()
    distance = np.full(len(translation), np.nan)
    if present.any():
        ego_xy = _vectors(ego.filter(ego.is_not_null()), 3)[:, :2]
        distance[present] = np.linalg.norm(translation[present, :2] - ego_xy, axis=1)
    return distance


def _box_velocity(ann: pl.DataFrame) -> np.ndarray:
    """(N, 3) velocities exactly as devkit `NuScenes.box_velocity(token, max_time_diff=1.5)`.

    first = prev (or the annotation itself at a track start), last = next (or itself at a track end);
    v = (pos_last - pos_first) / (1e-6 * t_last - 1e-6 * t_first) with *sample* timestamps; NaN for a
    track of one, or when the gap exceeds 1.5 s (3 s for a centred difference).
    """
    index = pl.DataFrame({"token": ann["token"], "_i": np.arange(ann.height)})

    def position_of(column: str) -> np.ndarray:
        joined = ann.select(pl.col(column).alias("token")).join(index, on="token", how="left", maintain_order="left")
        return joined["_i"].fill_null(-1).to_numpy()

    n = ann.height
    own = np.arange(n)
    prev_i, next_i = position_of("prev"), position_of("next")
    has_prev, has_next = prev_i >= 0, next_i >= 0
    first = np.where(has_prev, prev_i, own)
    last = np.where(has_next, next_i, own)
    translation = _vectors(ann["translation"], 3)
    seconds = 1e-6 * ann["timestamp"].to_numpy().astype(np.float64)  # the devkit's 1e-6 * timestamp
    time_diff = seconds[last] - seconds[first]
    limit = np.where(has_prev & has_next, 2 * MAX_VELOCITY_TIME_DIFF_S, MAX_VELOCITY_TIME_DIFF_S)
    with np.errstate(divide="ignore", invalid="ignore"):
        velocity = (translation[last] - translation[first]) / time_diff[:, None]
    invalid = ~(has_prev | has_next) | (time_diff > limit)
    velocity[invalid] = np.nan
    return velocity


def path_lengths(df: pl.DataFrame, group: str, order: str, position: str) -> pl.DataFrame:
    """Sum of 3D distances between consecutive positions of each group, in `order`."""
    ordered = df.select(group, order, position).sort(group, order)
    xyz = _vectors(ordered[position], 3)
    groups = ordered[group].to_numpy()
    step = np.zeros(len(xyz))
    if len(xyz) > 1:
        same = groups[1:] == groups[:-1]
        step[1:] = np.where(same, np.linalg.norm(np.diff(xyz, axis=0), axis=1), 0.0)
    return ordered.select(group).with_columns(_step=pl.Series(step)).group_by(group).agg(pl.col("_step").sum())


def _split_of(names: pl.Series, source_version: str) -> pl.Series:
    """Known nuScenes split per scene name; mini_* splits win for mini versions, null for unknown names."""
    splits = json.loads((resources.files("nuparquet") / "data" / "nuscenes_splits.json").read_text())
    order = (["mini_train", "mini_val"] if "mini" in source_version else []) + ["train", "val", "test"]
    lookup: dict[str, str] = {}
    for split in reversed(order):  # earlier entries of `order` overwrite later ones
        lookup.update(dict.fromkeys(splits[split], split))
    return names.replace_strict(lookup, default=None, return_dtype=pl.String)


def scene_counts(annotations: pl.DataFrame) -> pl.DataFrame:
    """scene_token -> num_annotations, num_instances (for a batch of whole scenes)."""
    return annotations.group_by("scene_token").agg(num_annotations=pl.len(),
                                                  num_instances=pl.col("instance_token").n_unique())


def build_scenes(t: dict[str, pl.DataFrame], references: pl.DataFrame, counts: pl.DataFrame,
                 source_version: str) -> pl.DataFrame:
    """One row per scene. `counts` is `scene_counts` of all annotations."""
    sample_ts = _as_int(t["sample"], "timestamp").select("token", "timestamp")
    ego_path = path_lengths(references, "scene_name", "timestamp", "ego_translation").rename(
        {"_step": "ego_distance_m"})
    scenes = (
        t["scene"]
        .join(t["log"].select(pl.col("token").alias("log_token"), "logfile", "vehicle", "date_captured",
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
    return scenes.with_columns(split=_split_of(scenes["name"], source_version))


def build_instances(t: dict[str, pl.DataFrame], annotation_times: pl.DataFrame, track_lengths: pl.DataFrame) -> pl.DataFrame:
    """One row per instance. `annotation_times`: token, scene_token, scene_name, timestamp of every
    annotation; `track_lengths`: path_lengths of the annotation centres per instance_token."""
    by_token = annotation_times.select("token", "scene_token", "scene_name", "timestamp")
    return (
        t["instance"]
        .join(t["category"].select(pl.col("token").alias("category_token"), pl.col("name").alias("category_name")),
              on="category_token", how="left")
        .join(by_token.rename({"token": "first_annotation_token", "timestamp": "first_timestamp"}),
              on="first_annotation_token", how="left")
        .join(by_token.select(pl.col("token").alias("last_annotation_token"), pl.col("timestamp").alias("last_timestamp")),
              on="last_annotation_token", how="left")
        .join(track_lengths.rename({"_step": "track_length_m"}), left_on="token", right_on="instance_token", how="left")
        .with_columns(track_length_m=pl.col("track_length_m").fill_null(0.0))
        .sort("scene_name", "first_timestamp", "token")
    )
