"""Canned analytics over a converted dataset: plain functions from LazyFrames to a LazyFrame.

Every query takes either a `nuparquet.dataset.Dataset` (it scans what it needs) or the LazyFrame(s) of the
dataset(s) it names, and returns a `polars.LazyFrame`: nothing is read until you `.collect()`. With
``scene="scene-0061"`` (or a list of names) the scene filter is applied first, so polars reads only the row
groups whose ``scene_name`` statistics can hold that scene (the datasets are sorted by scene).

    ds = nuparquet.open("OUT")
    class_distribution(ds).collect()                       # like NuScenes.list_categories()
    class_distribution(ds.scan("annotations"), by_scene=True, scene="scene-0061").collect()

Category and channel columns come out as plain strings, rows sorted by their keys. Standard deviations are
population deviations (ddof=0, as ``numpy.std``); quantiles interpolate linearly (as ``numpy.percentile``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, TypeAlias

import polars as pl

from nuparquet.channels import DEFAULT_REFERENCE_LIDAR

if TYPE_CHECKING:
    from nuparquet.dataset import Dataset

    Source: TypeAlias = Dataset | pl.LazyFrame | pl.DataFrame  # a Dataset, or the LazyFrame a query names
    Scene: TypeAlias = str | Sequence[str] | None
US_PER_S = 1_000_000
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


def _lazy(source, name: str) -> pl.LazyFrame:
    """`source` as the LazyFrame of dataset `name`: scanned from a Dataset, or taken as given."""
    if isinstance(source, pl.LazyFrame):
        return source
    if isinstance(source, pl.DataFrame):
        return source.lazy()
    if hasattr(source, "scan"):
        return source.scan(name)
    raise TypeError(f"expected a nuparquet Dataset or the {name!r} LazyFrame, got {type(source).__name__}")


def _second(source, given, name: str) -> pl.LazyFrame:
    """The second input of a two-dataset query: `given`, or scanned from `source` when that is a Dataset."""
    if given is not None:
        return _lazy(given, name)
    if hasattr(source, "scan"):
        return source.scan(name)
    raise TypeError(f"pass {name}= (a LazyFrame) or a Dataset as the first argument")


def _for_scene(lf: pl.LazyFrame, scene: str | Sequence[str] | None, column: str = "scene_name") -> pl.LazyFrame:
    if scene is None:
        return lf
    if isinstance(scene, str):
        return lf.filter(pl.col(column) == scene)
    return lf.filter(pl.col(column).is_in(list(scene)))


def _mean_std(expr: pl.Expr, name: str) -> list[pl.Expr]:
    return [expr.mean().alias(f"{name}_mean"), expr.std(ddof=0).alias(f"{name}_std")]


def _keys(by_scene: bool, *rest: str) -> list[str]:
    return (["scene_name"] if by_scene else []) + list(rest)


# --- annotations -----------------------------------------------------------------------------------------------

def class_distribution(annotations: Source, *, by_scene: bool = False, scene: Scene = None) -> pl.LazyFrame:
    """How many annotations and instances does each category have, and how big are its boxes?

    One row per category (per scene and category with ``by_scene=True``): ``num_annotations``,
    ``num_instances`` (distinct instance tokens among those annotations) and the mean and population standard
    deviation of ``width``, ``length``, ``height`` (metres, from ``size = [w, l, h]``) and ``lw_aspect`` =
    length / width: the numbers `NuScenes.list_categories()` prints, sorted by category name like it.
    """
    lf = _for_scene(_lazy(annotations, "annotations"), scene)
    width, length, height = (pl.col("size").arr.get(i) for i in range(3))
    return (
        lf.with_columns(pl.col("category_name").cast(pl.String))
        .group_by(_keys(by_scene, "category_name"))
        .agg(
            pl.len().alias("num_annotations"),
            pl.col("instance_token").n_unique().alias("num_instances"),
            *_mean_std(width, "width"), *_mean_std(length, "length"), *_mean_std(height, "height"),
            *_mean_std(length / width, "lw_aspect"),
        )
        .with_columns(pl.col("num_annotations", "num_instances").cast(pl.Int64))
        .sort(_keys(by_scene, "category_name"))
    )


def attribute_counts(annotations: Source, *, by_category: bool = False, scene: Scene = None) -> pl.LazyFrame:
    """How often is each attribute given to an annotation? (`NuScenes.list_attributes()`.)

    One row per attribute name (per category and attribute with ``by_category=True``): ``count`` = the number
    of annotations carrying it; an annotation with two attributes counts once for each, one without any
    counts nowhere. Sorted by attribute name.
    """
    lf = _for_scene(_lazy(annotations, "annotations"), scene)
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
    lf = _for_scene(_lazy(annotations, "annotations"), scene)
    return (
        lf.select(pl.col("category_name").cast(pl.String), "visibility_level")
        .group_by("category_name", "visibility_level")
        .agg(pl.len().cast(pl.Int64).alias("count"))
        .with_columns((pl.col("count") / pl.col("count").sum().over("category_name")).alias("share"))
        .sort("category_name", "visibility_level", nulls_last=True)
    )


def _point_stats(column: str, prefix: str) -> list[pl.Expr]:
    values = pl.col(column)
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
    numpy.percentile), max, and ``*_zero_share``: the share of boxes with no point at all (0..1).
    """
    lf = _for_scene(_lazy(annotations, "annotations"), scene)
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
    lf = _for_scene(_lazy(annotations, "annotations"), scene)
    bin_start = (pl.col("distance_to_ego_m") / bin_width_m).floor() * bin_width_m
    return (
        lf.select(pl.col("category_name").cast(pl.String), "distance_to_ego_m")
        .filter(pl.col("distance_to_ego_m").is_not_null())
        .group_by("category_name", bin_start.alias("bin_start_m"))
        .agg(pl.len().cast(pl.Int64).alias("count"))
        .select("category_name", "bin_start_m", (pl.col("bin_start_m") + bin_width_m).alias("bin_end_m"), "count")
        .sort("category_name", "bin_start_m")
    )


# --- instances -------------------------------------------------------------------------------------------------

def track_stats(instances: Source, *, by_scene: bool = False, scene: Scene = None) -> pl.LazyFrame:
    """How long are the tracks (instances) of each category, in annotations, seconds and metres?

    One row per category (per scene and category with ``by_scene=True``; an instance belongs to the scene of
    its first annotation): ``num_tracks``; mean / median / max of ``nbr_annotations`` (``annotations_*``),
    of the duration last minus first annotation timestamp (``duration_s_*``) and of ``track_length_m``
    (path length of the box centres, ``length_m_*``).
    """
    lf = _for_scene(_lazy(instances, "instances"), scene)
    duration_s = (pl.col("last_timestamp") - pl.col("first_timestamp")) / US_PER_S

    def mmm(expr: pl.Expr, name: str) -> list[pl.Expr]:
        return [expr.mean().alias(f"{name}_mean"), expr.median().alias(f"{name}_median"),
                expr.max().alias(f"{name}_max")]

    return (
        lf.with_columns(pl.col("category_name").cast(pl.String))
        .group_by(_keys(by_scene, "category_name"))
        .agg(pl.len().cast(pl.Int64).alias("num_tracks"), *mmm(pl.col("nbr_annotations"), "annotations"),
             *mmm(duration_s, "duration_s"), *mmm(pl.col("track_length_m"), "length_m"))
        .sort(_keys(by_scene, "category_name"))
    )


# --- scenes ----------------------------------------------------------------------------------------------------

def scene_summary(scenes: Source, annotations: Source | None = None, *, scene: Scene = None) -> pl.LazyFrame:
    """What does each scene hold? (`NuScenes.list_scenes()`, and more.)

    One row per scene, sorted by start time as list_scenes: ``name``, ``description``, ``start_utc`` (first
    sample time), ``date_captured``, ``duration_s``, ``log_location``, ``vehicle``, ``nbr_samples``,
    ``num_annotations`` (all samples), ``num_annotations_list_scenes`` (the ``#anns`` list_scenes prints: it
    leaves out the annotations of the scene's last sample), ``num_instances``, ``ego_distance_m``.
    Needs the scenes and annotations datasets.
    """
    scenes_lf = _for_scene(_lazy(scenes, "scenes"), scene, column="name")
    annotations_lf = _for_scene(_second(scenes, annotations, "annotations"), scene)
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


# --- frames ----------------------------------------------------------------------------------------------------

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
    lf = _for_scene(_lazy(frames, "frames"), scene)
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
    lf = _for_scene(_lazy(frames, "frames"), scene)
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
        .select(*_keys(by_scene, "channel"), "modality", "num_frames", "num_keyframes", "num_sweeps",
                "frame_hz", "keyframe_hz")
        .sort(_keys(by_scene, "channel"))
    )


# --- everything `nuparquet stats` prints -----------------------------------------------------------------------

SECTIONS = ("scenes", "class_distribution", "attributes", "visibility", "points_per_box", "distance_histogram",
            "tracks", "ego_speed", "channel_rates")
EXTRA_SECTIONS = ("class_distribution_by_scene", "channel_rates_by_scene", "ego_motion")


def summary(ds: Dataset, *, scene: Scene = None, sections: Sequence[str] = SECTIONS,
            bin_width_m: float = 10.0) -> dict[str, pl.LazyFrame]:
    """The canned results `nuparquet stats` prints, by section name (`SECTIONS`; `EXTRA_SECTIONS` on request)."""
    builders = {
        "scenes": lambda: scene_summary(ds, scene=scene),
        "class_distribution": lambda: class_distribution(ds, scene=scene),
        "class_distribution_by_scene": lambda: class_distribution(ds, by_scene=True, scene=scene),
        "attributes": lambda: attribute_counts(ds, scene=scene),
        "visibility": lambda: visibility_by_category(ds, scene=scene),
        "points_per_box": lambda: points_per_box(ds, scene=scene),
        "distance_histogram": lambda: distance_histogram(ds, bin_width_m=bin_width_m, scene=scene),
        "tracks": lambda: track_stats(ds, scene=scene),
        "ego_speed": lambda: ego_speed_summary(ds, scene=scene),
        "ego_motion": lambda: ego_motion(ds, scene=scene),
        "channel_rates": lambda: channel_rates(ds, scene=scene),
        "channel_rates_by_scene": lambda: channel_rates(ds, by_scene=True, scene=scene),
    }
    unknown = [s for s in sections if s not in builders]
    if unknown:
        raise ValueError(f"unknown section(s) {', '.join(unknown)}; valid: {', '.join(builders)}")
    return {name: builders[name]() for name in sections}
