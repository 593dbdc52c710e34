"""`objects/` and `surfaces/` of a nuImages conversion: one row per object_ann / surface_ann, with its category
(and attributes), its box, its mask as the source's RLE plus its area, and its image's calibration and ego pose.

Both are "whole" builders (a nuImages dataset has no scenes to batch by); their rows are sorted by image, then by
the record's place in its file, which is the order the devkit draws an image's annotations in.
"""

from __future__ import annotations

import polars as pl

from nuparquet.conversion.builder import BuildContext, Builder
from nuparquet.sources.nuimages import intrinsics, mask_facts

_F64 = pl.Float64


def _floats(name: str, size: int | None, frame: pl.DataFrame, alias: str | None = None) -> pl.Expr:
    """A list column of the source (numbers as inferred: integers where every value was one) as float64: an array
    of `size`, or a list (size None)."""
    column = pl.col(name)
    if isinstance(frame.schema[name], pl.Array):
        column = column.arr.to_list()
    column = column.cast(pl.List(_F64))
    return (column.list.to_array(size) if size else column).alias(alias or name)


def image_rows(ctx: BuildContext) -> pl.DataFrame:
    """Every image (sample_data) with its sample's log, its camera, calibration and ego pose (memoised)."""
    def compute() -> pl.DataFrame:
        t = ctx.tables
        calibrated = t["calibrated_sensor"]
        calibrations = calibrated.select(
            pl.col("token").alias("calibrated_sensor_token"), "sensor_token",
            _floats("translation", 3, calibrated, "sensor_translation"),
            _floats("rotation", 4, calibrated, "sensor_rotation"),
            pl.Series("camera_intrinsic", intrinsics(calibrated), pl.List(_F64)).list.to_array(9),
            _floats("camera_distortion", None, calibrated))
        poses = t["ego_pose"]
        poses = poses.select(pl.col("token").alias("ego_pose_token"), _floats("translation", 3, poses, "ego_translation"),
                             _floats("rotation", 4, poses, "ego_rotation"), pl.col("speed").cast(_F64).alias("ego_speed"))
        logs = t["log"].select(pl.col("token").alias("log_token"), pl.col("location").alias("log_location"), "vehicle")
        return (t["sample_data"].select(pl.col("token").alias("sample_data_token"), "sample_token", "ego_pose_token",
                                        "calibrated_sensor_token", "timestamp", "filename", "width", "height")
                .join(t["sample"].select(pl.col("token").alias("sample_token"), "log_token"), on="sample_token",
                      how="left", maintain_order="left")
                .join(logs, on="log_token", how="left", maintain_order="left")
                .join(calibrations, on="calibrated_sensor_token", how="left", maintain_order="left")
                .join(t["sensor"].select(pl.col("token").alias("sensor_token"), "channel"), on="sensor_token",
                      how="left", maintain_order="left")
                .join(poses, on="ego_pose_token", how="left", maintain_order="left"))
    return ctx.shared("nuimages_images", compute)


def _annotation_rows(ctx: BuildContext, table: str) -> pl.DataFrame:
    """One mask table's records with their masks' facts, category and image rows, sorted by image and file order."""
    source = ctx.tables[table]
    facts, _ = mask_facts(source, f"{table}.json")  # the problems stopped the conversion before the builders ran
    categories = ctx.tables["category"].select(pl.col("token").alias("category_token"),
                                               pl.col("name").alias("category_name"))
    rows = (pl.concat([source.with_row_index("file_index").with_columns(pl.col("file_index").cast(pl.Int64)), facts],
                      how="horizontal")
            .join(categories, on="category_token", how="left", maintain_order="left")
            .join(image_rows(ctx), on="sample_data_token", how="left", maintain_order="left"))
    return rows.sort("sample_data_token", "file_index")


def build_objects(ctx: BuildContext) -> pl.DataFrame:
    rows = _annotation_rows(ctx, "object_ann")
    attributes = ctx.tables["attribute"]
    tokens = pl.col("attribute_tokens").cast(pl.List(pl.String))
    names = tokens.list.eval(pl.element().replace_strict(attributes["token"], attributes["name"], default=None))
    return rows.with_columns(tokens.alias("attribute_tokens"), names.alias("attribute_names"))


def build_surfaces(ctx: BuildContext) -> pl.DataFrame:
    return _annotation_rows(ctx, "surface_ann")


OBJECTS = Builder("objects", build_objects, scope="whole", schema="objects", group_by=None)
SURFACES = Builder("surfaces", build_surfaces, scope="whole", schema="surfaces", group_by=None)
BUILDERS: tuple[Builder, ...] = (OBJECTS, SURFACES)
