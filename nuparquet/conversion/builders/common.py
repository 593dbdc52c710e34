"""Inputs several builders share, memoised on the build context (computed once per conversion)."""

from __future__ import annotations

import polars as pl

from nuparquet.conversion import lookups
from nuparquet.conversion.builder import BuildContext
from nuparquet.schemas import table_schemas


def samples(ctx: BuildContext) -> pl.DataFrame:
    """`lookups.sample_lookup`: sample_token -> scene, log location, sample timestamp."""
    return ctx.shared("samples", lambda: lookups.sample_lookup(ctx.tables))


def reference_poses(ctx: BuildContext) -> pl.DataFrame:
    """`lookups.reference_poses`: per sample, the reference lidar keyframe's timestamp and ego translation."""
    return ctx.shared("reference_poses", lambda: lookups.reference_poses(ctx.tables, samples(ctx)))


def file_positions(ctx: BuildContext, table: str) -> pl.DataFrame:
    """token -> `file_index` (uint32): each record's position in its JSON file, the devkit's list index
    (`nusc.sample_annotation[i]`, `nusc.instance[i]`; a sample's `anns` list follows it)."""
    return ctx.shared(f"file_positions/{table}", lambda: ctx.tables[table].select("token").with_row_index("file_index"))


def declared_fields(rows: pl.DataFrame, table: str) -> pl.DataFrame:
    """`rows` of source table `table` with only the fields its schema declares: a field the source adds (a
    `category_name` in sample_annotation, kept as JSON text in tables/) must not shadow a column a join adds."""
    names = [f.name for f in table_schemas()[table].fields if f.name in rows.columns]
    return rows if len(names) == rows.width else rows.select(names)
