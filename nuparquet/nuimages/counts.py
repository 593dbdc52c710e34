"""The counts the devkit's `NuImages.list_categories` and `list_attributes` print, as DataFrames."""

from __future__ import annotations

from collections.abc import Sequence

import polars as pl

from nuparquet.nuimages.masks import check_nuimages


def category_counts(ds, sample_tokens: Sequence[str] | None = None) -> pl.DataFrame:
    """name, description, object_anns, surface_anns per category (of `sample_tokens` only, when given), in
    category.json's order, categories with neither left out (as `list_categories` prints them)."""
    check_nuimages(ds)
    counts = []
    for kind, column in (("objects", "object_anns"), ("surfaces", "surface_anns")):
        rows = ds.scan(kind)
        if sample_tokens is not None:
            rows = rows.filter(pl.col("sample_token").is_in(list(sample_tokens)))
        counts.append(rows.group_by("category_token").agg(pl.len().cast(pl.Int64).alias(column)))
    categories = ds.scan("tables/category").select(pl.col("token").alias("category_token"), "name", "description")
    for frame in counts:
        categories = categories.join(frame, on="category_token", how="left", maintain_order="left")
    return (categories.with_columns(pl.col("object_anns", "surface_anns").fill_null(0))
            .filter((pl.col("object_anns") > 0) | (pl.col("surface_anns") > 0)).drop("category_token").collect())


def attribute_counts(ds) -> pl.DataFrame:
    """name, description, annotations per attribute (object_anns carrying it), in attribute.json's order, every
    attribute listed (as `list_attributes` prints them)."""
    check_nuimages(ds)
    used = (ds.scan("objects").select(pl.col("attribute_tokens").explode().alias("token")).drop_nulls()
            .group_by("token").agg(pl.len().cast(pl.Int64).alias("annotations")))
    return (ds.scan("tables/attribute").select("token", "name", "description")
            .join(used, on="token", how="left", maintain_order="left")
            .with_columns(pl.col("annotations").fill_null(0)).drop("token").collect())
