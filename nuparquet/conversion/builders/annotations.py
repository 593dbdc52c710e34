"""`annotations/`: one row per sample_annotation, joined, with velocity (as the devkit's box_velocity), yaw and
distance to the ego vehicle."""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.geometry import quaternions
from nuparquet.columns import to_numpy
from nuparquet.conversion.builders.common import declared_fields, file_positions, reference_poses, samples
from nuparquet.conversion.builder import BuildContext, Builder, SceneBatch

# devkit NuScenes.box_velocity's default: neighbours further apart than this (doubled for a centred
# difference) give NaN.
MAX_VELOCITY_TIME_DIFF_S = 1.5


def build_annotations(tables: dict[str, pl.DataFrame], annotations: pl.DataFrame, samples: pl.DataFrame,
                      references: pl.DataFrame, positions: pl.DataFrame, *,
                      allow_dangling: bool = False) -> pl.DataFrame:
    """One row per row of `annotations` (sample_annotation rows of a batch of scenes). `references` is
    `lookups.reference_poses(tables, samples)`. `allow_dangling` (a trimmed extract): velocity is null where the devkit's
    box_velocity fails (`velocity_defined`); joins without a partner give nulls in any case. `positions`: token ->
    file_index of every sample_annotation record (`common.file_positions`)."""
    names = dict(zip(tables["attribute"]["token"].to_list(), tables["attribute"]["name"].to_list()))  # a handful
    ann = declared_fields(annotations, "sample_annotation").with_columns(
        attribute_names=pl.col("attribute_tokens").list.eval(
            pl.element().replace_strict(names, default=None, return_dtype=pl.String)))
    ego = references.select("sample_token", pl.col("ego_translation").alias("_ego"))
    ann = (
        ann.lazy()
        .join(samples.lazy(), on="sample_token", how="left")
        .rename({"sample_timestamp": "timestamp"})
        .join(tables["instance"].lazy().select(pl.col("token").alias("instance_token"), "category_token"),
              on="instance_token", how="left")
        .join(tables["category"].lazy().select(pl.col("token").alias("category_token"),
                                               pl.col("name").cast(pl.Categorical).alias("category_name")),
              on="category_token", how="left")
        .join(ego.lazy(), on="sample_token", how="left")
        .join(visibility_levels(tables["visibility"]).lazy(), on="visibility_token", how="left")
        .join(positions.lazy(),
              on="token", how="left")
        .collect()
    )
    translation = to_numpy(ann["translation"], (3,))
    velocity = pl.Series(box_velocity(ann), dtype=pl.Array(pl.Float64, 3))
    if allow_dangling:
        velocity = pl.select(pl.when(pl.Series(velocity_defined(ann))).then(velocity)).to_series()
    ann = ann.with_columns(
        velocity=velocity,
        yaw=pl.Series(quaternions.yaw_from_quaternions(to_numpy(ann["rotation"], (4,)))),
        distance_to_ego_m=pl.Series(_xy_distance(translation, ann["_ego"])).fill_nan(None),
    )
    return ann.drop("_ego", "category_token").sort("scene_name", "timestamp", "instance_token", "token")


def visibility_levels(visibility: pl.DataFrame) -> pl.DataFrame:
    """visibility_token -> visibility_level (ordinal), visibility_name, visibility_description, from the table.

    The ordinal exists only where the table gives one: levels that are numeric ranges ("v0-40", "v40-60", ...),
    ranked by their lower bound (nuScenes: 1..4). Worded levels (T4: "full", "most", ...) get none; the token is
    never parsed (T4's tokens are hashes)."""
    bounds = visibility["level"].str.extract(r"^v?(\d+(?:\.\d+)?)\s*-\s*\d+(?:\.\d+)?%?$", 1).cast(pl.Float64, strict=False)
    ranked = bounds.rank("dense").cast(pl.Int8) if bounds.null_count() == 0 and len(bounds) else pl.repeat(
        None, len(visibility), dtype=pl.Int8, eager=True)
    return visibility.select(pl.col("token").alias("visibility_token"),
                             ranked.alias("visibility_level"), pl.col("level").cast(pl.Categorical).alias("visibility_name"),
                             pl.col("description").cast(pl.Categorical).alias("visibility_description"))


def _xy_distance(translation: np.ndarray, ego: pl.Series) -> np.ndarray:
    """xy distance of each box centre to its ego position; NaN where there is none (null rows are NaN rows)."""
    return np.linalg.norm(translation[:, :2] - to_numpy(ego, (3,))[:, :2], axis=1)


def box_velocity(ann: pl.DataFrame) -> np.ndarray:
    """(N, 3) velocities exactly as devkit `NuScenes.box_velocity(token, max_time_diff=1.5)`.

    first = prev (or the annotation itself at a track start), last = next (or itself at a track end);
    v = (pos_last - pos_first) / (1e-6 * t_last - 1e-6 * t_first) with *sample* timestamps; NaN for a
    track of one, or when the gap exceeds 1.5 s (3 s for a centred difference).
    """
    index = pl.DataFrame({"token": ann["token"], "_i": np.arange(ann.height)})

    def position_of(column: str) -> np.ndarray:
        joined = ann.select(pl.col(column).alias("token")).join(index, on="token", how="left", maintain_order="left")
        return joined["_i"].fill_null(-1).to_numpy()

    own = np.arange(ann.height)
    prev_i, next_i = position_of("prev"), position_of("next")
    has_prev, has_next = prev_i >= 0, next_i >= 0
    first = np.where(has_prev, prev_i, own)
    last = np.where(has_next, next_i, own)
    translation = to_numpy(ann["translation"], (3,))
    seconds = 1e-6 * ann["timestamp"].to_numpy().astype(np.float64)  # the devkit's 1e-6 * timestamp
    time_diff = seconds[last] - seconds[first]
    limit = np.where(has_prev & has_next, 2 * MAX_VELOCITY_TIME_DIFF_S, MAX_VELOCITY_TIME_DIFF_S)
    with np.errstate(divide="ignore", invalid="ignore"):
        velocity = (translation[last] - translation[first]) / time_diff[:, None]
    invalid = ~(has_prev | has_next) | (time_diff > limit)
    velocity[invalid] = np.nan
    return velocity


def velocity_defined(ann: pl.DataFrame) -> np.ndarray:
    """(N,) False where devkit `box_velocity` raises instead of answering, as it does on a trimmed extract: a
    non-empty prev or next naming no annotation (of `ann`), or no sample timestamp for the annotation or for the
    neighbours it reads (both for a centred difference, itself and one for a track end). A track of one answers
    NaN without reading anything: defined."""
    index = pl.DataFrame({"token": ann["token"], "_i": np.arange(ann.height)})
    known = ann["timestamp"].is_not_null().to_numpy()
    defined = np.ones(ann.height, dtype=bool)
    named = {}
    for column in ("prev", "next"):
        named[column] = (ann[column] != "").to_numpy()
        joined = ann.select(pl.col(column).alias("token")).join(index, on="token", how="left", maintain_order="left")
        position = joined["_i"].fill_null(-1).to_numpy()
        defined &= ~named[column] | ((position >= 0) & known[np.maximum(position, 0)])
    reads_itself = named["prev"] ^ named["next"]
    return defined & (known | ~reads_itself)


def build(ctx: BuildContext, batch: SceneBatch) -> pl.DataFrame:
    return build_annotations(ctx.tables, batch.rows["sample_annotation"], samples(ctx), reference_poses(ctx),
                             allow_dangling=ctx.options.allow_dangling,
                             positions=file_positions(ctx, "sample_annotation"))


BUILDER = Builder("annotations", build, schema="annotations")
