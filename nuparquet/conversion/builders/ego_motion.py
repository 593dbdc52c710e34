"""`sample_ego_motion/` of a TruckScenes conversion: one row per sample with its `ego_motion_cabin` and
`ego_motion_chassis` aligned to it as the CAN bus is to a nuScenes sample (`nuparquet.can_bus.align`: the record
at or before the sample, its age, the float fields interpolated), and the record the devkit's
`getclosest(table, sample timestamp)` returns.

The ego-motion tables are one timeline for the whole version (they name no scene), so each sample looks through
all of it; the interpolation never spans more than `align.MAX_INTERPOLATION_GAP_US`, so never two scenes.
"""

from __future__ import annotations

import polars as pl

from nuparquet.can_bus.align import aligned
from nuparquet.conversion.builder import BuildContext, Builder
from nuparquet.conversion.builders.common import samples
from nuparquet.geometry.interpolation import closest_rows

TABLES = ("ego_motion_cabin", "ego_motion_chassis")


def sample_ego_motion(rows: pl.DataFrame, table: str, records: pl.DataFrame) -> pl.DataFrame:
    """`table`'s four columns for `rows` (a `timestamp` each): `<table>` (struct: the record at or before, null
    before the first), `<table>_age_us`, `<table>_interp` (struct of the float fields) and `<table>_closest_token`.
    `records`: the table in file order."""
    names = records.columns
    messages = (records.rename({"timestamp": "utime"}).sort("utime", maintain_order=True)
                .select(pl.lit("").alias("scene_name"), pl.all()))
    stream = rows.select(pl.lit("").alias("scene_name"), "timestamp")
    out = aligned(stream, table, messages).with_columns(pl.col(table).struct.rename_fields(names))
    if records.height:
        closest = records["token"].gather(closest_rows(records["timestamp"].to_numpy(), rows["timestamp"].to_numpy()))
    else:
        closest = pl.Series(values=[None] * rows.height, dtype=pl.String)
    return out.with_columns(closest.alias(f"{table}_closest_token"))


def build(ctx: BuildContext) -> pl.DataFrame:
    rows = (samples(ctx).select("sample_token", "scene_token", "scene_name", pl.col("sample_timestamp").alias("timestamp"))
            .sort("scene_name", "timestamp", "sample_token"))
    return pl.concat([rows, *(sample_ego_motion(rows, t, ctx.tables[t]) for t in TABLES)], how="horizontal")


def _wanted(ctx: BuildContext) -> str | None:
    missing = [t for t in TABLES if t not in ctx.tables]
    return f"no {' or '.join(missing)} table" if missing else None


BUILDER = Builder("sample_ego_motion", build, scope="whole", schema="sample_ego_motion", wanted=_wanted)
