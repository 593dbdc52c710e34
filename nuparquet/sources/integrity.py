"""Referential and numeric integrity of parsed source tables, driven by the schema files.

Every foreign key is declared in `schemas/tables` (`"ref"`), so this module holds no list of joins of its
own: it walks the schemas. All checks are polars anti-joins / aggregations, never a loop over records.
"""

from __future__ import annotations

import polars as pl

from nuparquet.problems import MAX_REPORTED, Problem, echo
from nuparquet.schemas import Schema, table_schemas

QUATERNION_NORM_TOLERANCE = 1e-6
# Norms this close to 1 are accepted with a warning: quaternions written to 4 decimals (norm 0.99997) are unit
# quaternions to the devkit, which normalises them (pyquaternion), and so does nuparquet's geometry.
QUATERNION_NEAR_UNIT = 1e-3
# Timestamps are microseconds since 1970 (nuScenes, Lyft, T4); values outside 2000..2100 in that unit are in
# another unit. They convert (the data is kept as it is), with a warning naming the field and the range.
PLAUSIBLE_TIMESTAMP_US = (946_684_800_000_000, 4_102_444_800_000_000)

# Counts stored in one table that must equal the number of referring records in another:
# (table, count field, referring table, referring field).
_COUNTS = [("scene", "nbr_samples", "sample", "scene_token"),
           ("instance", "nbr_annotations", "sample_annotation", "instance_token")]


def check_integrity(tables: dict[str, pl.DataFrame], limit: int = MAX_REPORTED, *, references: bool = True,
                    schemas: dict[str, Schema] | None = None) -> list[Problem]:
    """All problems across the parsed tables (by table name): unique tokens, resolving foreign keys
    (including every non-empty prev/next), count fields, and finite unit quaternions. At most `limit`
    problems per check, plus a count of the rest. `references=False` leaves out the foreign keys and count fields
    (`--allow-dangling`: `nuparquet.sources.dangling` finds those in full). `schemas`: the tables' schemas, when not
    nuScenes' (`nuparquet.schemas.family_table_schemas`)."""
    schemas = table_schemas() if schemas is None else schemas
    # Extra tables (typed by inference, no schema) have no declared keys to check.
    frames = {name: df.with_row_index("_idx") for name, df in tables.items() if name in schemas}
    files = {name: schemas[name].source for name in frames}
    problems: list[Problem] = []

    def report(table: str, rows: pl.DataFrame, message, warning: bool = False) -> None:
        for row in rows.head(limit).iter_rows(named=True):
            problems.append(Problem(files[table], message(row), row["_idx"], row.get("token"), warning=warning))
        if rows.height > limit:
            problems.append(Problem(files[table], f"{rows.height - limit} more like the above",
                                    omitted=rows.height - limit, warning=warning))

    for name, df in frames.items():
        schema = schemas[name]
        if df["token"].n_unique() < df.height:  # (counting is ~3x faster than marking every row: mark only then)
            report(name, df.filter(pl.col("token").is_duplicated()), lambda r: "duplicate token")
        for f in schema.fields:
            if f.ref is None or f.ref not in frames or f.name not in df.columns or not references:
                continue
            targets = frames[f.ref].select(pl.col("token").alias("_ref"))
            values = df.select("_idx", "token", pl.col(f.name).alias("_ref"))
            if f.type.startswith("list"):
                values = values.explode("_ref").drop_nulls("_ref")
            if f.empty_ok:
                values = values.filter(pl.col("_ref") != "")
            dangling = values.join(targets, on="_ref", how="anti").sort("_idx")
            report(name, dangling, lambda r, f=f: f"{f.name} {echo(r['_ref'])} does not resolve to a {f.ref} record")
        for f in schema.fields:
            if f.quaternion and f.name in df.columns:
                q = df.select("_idx", "token", pl.col(f.name).arr.to_list().alias("_q"))
                norm = q.select("_idx", "token", "_q", (pl.col("_q").list.eval(pl.element() ** 2).list.sum().sqrt()).alias("_n"))
                off = (pl.col("_n") - 1.0).abs()
                bad = norm.filter(~pl.col("_n").is_finite() | (off > QUATERNION_NEAR_UNIT))
                report(name, bad, lambda r, f=f: f"{f.name} {r['_q']} is not a finite unit quaternion (norm {r['_n']})")
                near = norm.filter(pl.col("_n").is_finite() & (off > QUATERNION_NORM_TOLERANCE) & (off <= QUATERNION_NEAR_UNIT))
                report(name, near, lambda r, f=f: f"{f.name} {r['_q']} has norm {r['_n']:.6f}, not 1 to 1e-6: accepted "
                                                  "and normalised (as the devkit does)", warning=True)
        for f in schema.fields:
            if (f.finite or f.non_negative) and f.name in df.columns and df.schema[f.name] != pl.Null:
                report(name, _out_of_range(df, f), lambda r, f=f: f"{f.name} {echo(r['_v'], quote=False)} "
                       + ("must be finite" if f.finite and not f.non_negative else
                          "must be >= 0" if not f.finite else "must be finite and >= 0"))
    problems += _timestamp_units(frames, files)
    report("sample_data", _second_keyframes(frames), lambda r: f"is a second keyframe of {r['_channel']} for sample "
           f"{r['sample_token']} (the first is {r['_first']}): a sample holds one keyframe per channel")
    for table, count_field, referring, ref_field in _COUNTS:
        if table not in frames or referring not in frames or not references:
            continue
        counts = frames[referring].group_by(ref_field).agg(pl.len().alias("_actual"))
        joined = frames[table].join(counts, left_on="token", right_on=ref_field, how="left").with_columns(
            pl.col("_actual").fill_null(0)).sort("_idx")
        bad = joined.filter(pl.col(count_field) != pl.col("_actual"))
        report(table, bad, lambda r, c=count_field, ref=referring: f"{c} is {r[c]} but {r['_actual']} {ref} records refer to it")
    return problems


def _second_keyframes(frames: dict[str, pl.DataFrame]) -> pl.DataFrame:
    """The keyframes after a sample's first of the same sensor (_idx, token, sample_token, _channel, _first).

    A sample holds one keyframe per sensor: the devkit's `sample['data']` keeps one token per channel (the last in
    file order) and every per-sample pairing here takes that one, so a second keyframe would make them disagree."""
    if "sample_data" not in frames or "calibrated_sensor" not in frames:
        return pl.DataFrame()
    keyframes = (frames["sample_data"].filter(pl.col("is_key_frame"))
                 .join(frames["calibrated_sensor"].select(pl.col("token").alias("calibrated_sensor_token"),
                                                          "sensor_token"),
                       on="calibrated_sensor_token", how="inner")  # a dangling calibration is reported on its own
                 .sort("_idx"))
    if keyframes.select("sample_token", "sensor_token").is_duplicated().not_().all():
        return pl.DataFrame()
    channel = (keyframes.join(frames["sensor"].select(pl.col("token").alias("sensor_token"), pl.col("channel")),
                              on="sensor_token", how="left", maintain_order="left")["channel"]
               if "sensor" in frames else keyframes["sensor_token"])
    return (keyframes.with_columns(channel.fill_null(keyframes["sensor_token"]).alias("_channel"),
                                   pl.col("token").first().over("sample_token", "sensor_token").alias("_first"))
            .filter(pl.col("token") != pl.col("_first")))


def _out_of_range(df: pl.DataFrame, f) -> pl.DataFrame:
    """Rows whose value of `f` (any element of a list) is NaN or infinite (`f.finite`) or below 0 (`f.non_negative`;
    NaN is no value below 0: Lyft writes NaN widths for lidar rows)."""
    is_list = isinstance(df.schema[f.name], (pl.Array, pl.List))
    values = pl.col(f.name).arr.to_list() if isinstance(df.schema[f.name], pl.Array) else pl.col(f.name)

    def bad(x: pl.Expr) -> pl.Expr:
        conditions = ([~x.is_finite()] if f.finite else []) + ([x < 0] if f.non_negative else [])
        return pl.any_horizontal(conditions)

    flag = values.list.eval(bad(pl.element())).list.any() if is_list else bad(values)
    return df.select("_idx", "token", values.alias("_v"), flag.fill_null(False).alias("_bad")).filter("_bad").sort("_idx")


def _timestamp_units(frames: dict[str, pl.DataFrame], files: dict[str, str]) -> list[Problem]:
    """A warning per table whose `timestamp` values are not plausible microseconds, with a guess at their unit."""
    warnings = []
    low, high = PLAUSIBLE_TIMESTAMP_US
    for name, df in frames.items():
        if "timestamp" not in df.columns or df.height == 0 or not df.schema["timestamp"].is_numeric():
            continue
        lo, hi = df["timestamp"].min(), df["timestamp"].max()
        if lo is None or (low <= lo and hi <= high):
            continue
        scale = hi if hi > high else lo
        unit = ("nanoseconds" if scale > high * 100 else "milliseconds" if scale < low / 100 and scale > low / 1e5
                else "seconds" if scale < low / 1e5 else "another unit")
        warnings.append(Problem(files[name], f"timestamp values {lo:g}..{hi:g} are not microseconds between 2000 and "
                                             f"2100 (they look like {unit}); converted as they are", warning=True))
    return warnings
