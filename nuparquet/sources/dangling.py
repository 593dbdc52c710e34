"""Dangling references of a trimmed extract, found in full: what `convert --allow-dangling` accepts and reports.

Real nuScenes-format data in public repositories is usually cut down: one keyframe of a scene beside the full
`instance`, `calibrated_sensor`, `log` and `map` tables, a scene whose `last_sample_token` and `next` pointers lead
nowhere, instances whose first annotation is absent. The devkit loads such a folder; the strict default of nuparquet
refuses it (`validate.check_integrity`: a reference that names no record, a count field that disagrees with the
records referring to it). With `--allow-dangling` exactly these two checks become findings:

- `find(tables)`: every one of them, one row each (`schemas/findings.json`): the references the schemas declare
  (`"ref"`, the ones `check_integrity` checks, all of them rather than the first 50 per check), and in the extra
  tables no schema describes (nuImages-style `object_ann`, `surface_ann` beside the 3D tables) the fields named
  after a table present, as nuScenes names every key: `<table>_token`, `<table>_tokens` (strict conversion never
  checked those, and still does not);
- `summary(findings)` / `manifest_entry` / `summary_lines`: counts by table and field, for the manifest
  (`dangling`) and one warning line each;
- `warnings(findings)`: the findings worded as the strict check words them, as warnings (`validate --allow-dangling`).

Nothing is invented: the derived datasets keep their rows, with nulls where a join has no partner (the
`null_if_dangling` columns of the schemas). Every other check stays an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import polars as pl

from nuparquet.problems import MAX_REPORTED, Problem, echo
from nuparquet.schemas import dataset_schemas, table_schemas
from nuparquet.sources.integrity import _COUNTS as COUNTS

DATASET = "findings"
REFERENCE, COUNT = "dangling_reference", "count_mismatch"


@dataclass(frozen=True)
class Finding(Problem):
    """A dangling reference or count mismatch accepted with `--allow-dangling`: a warning, worded as the strict
    check words the error."""


@dataclass(frozen=True)
class Reference:
    table: str
    field: str
    target: str
    is_list: bool = False
    empty_ok: bool = False  # "" means "none" (prev/next)


def references(tables: dict[str, pl.DataFrame]) -> list[Reference]:
    """The references to check among `tables` (both ends present): the schemas' declared ones, in schema order, then
    those of the extra tables by their field names (`sample_data_token` -> sample_data, `attribute_tokens` ->
    attribute), in table and column order."""
    out = []
    for name, schema in table_schemas().items():
        if name not in tables:
            continue
        out += [Reference(name, f.name, f.ref, f.type.startswith("list"), f.empty_ok) for f in schema.fields
                if f.ref is not None and f.ref in tables and f.name in tables[name].columns]
    for name in sorted(set(tables) - set(table_schemas())):
        for column, dtype in tables[name].schema.items():
            target, is_list = column.removesuffix("_tokens"), True
            if target == column:
                target, is_list = column.removesuffix("_token"), False
            if target == column or target not in tables or "token" not in tables[target].columns:
                continue
            strings = (isinstance(dtype, (pl.List, pl.Array)) and dtype.inner == pl.String) if is_list else dtype == pl.String
            if strings:  # typed by inference: a list of equal lengths is a fixed-size one, a list of [] holds no strings
                out.append(Reference(name, column, target, is_list))
    return out


def find(tables: dict[str, pl.DataFrame]) -> pl.DataFrame:
    """Every dangling reference (`references`) and count mismatch of the parsed tables (by name), in that order, each
    by record and list position. Columns and types of `schemas/findings.json`."""
    parts = []
    for ref in references(tables):
        rows = tables[ref.table].with_row_index("_idx")
        token = pl.col("token") if "token" in rows.columns else pl.lit(None, pl.String)
        column = pl.col(ref.field)
        if isinstance(rows.schema[ref.field], pl.Array):
            column = column.arr.to_list()
        values = rows.select("_idx", token.alias("_token"), column.alias("_ref"))
        if ref.is_list:
            values = (values.with_columns(_pos=pl.int_ranges(pl.col("_ref").list.len(), dtype=pl.Int32))
                      .explode("_ref", "_pos").drop_nulls("_ref"))
        else:
            values = values.with_columns(_pos=pl.lit(None, pl.Int32))
        if ref.empty_ok:
            values = values.filter(pl.col("_ref") != "")
        targets = tables[ref.target].select(pl.col("token").alias("_ref"))
        dangling = values.join(targets, on="_ref", how="anti").sort("_idx", "_pos")
        parts.append(dangling.select(
            kind=pl.lit(REFERENCE), table=pl.lit(ref.table), field=pl.lit(ref.field), target=pl.lit(ref.target),
            record_index=pl.col("_idx").cast(pl.Int64), token="_token", reference="_ref", position="_pos",
            stated=pl.lit(None, pl.Int64), actual=pl.lit(None, pl.Int64)))
    for table, count_field, referring, ref_field in COUNTS:
        if table not in tables or referring not in tables:
            continue
        counts = tables[referring].group_by(ref_field).agg(pl.len().alias("_actual"))
        joined = tables[table].with_row_index("_idx").join(counts, left_on="token", right_on=ref_field, how="left")
        bad = joined.with_columns(pl.col("_actual").fill_null(0)).filter(pl.col(count_field) != pl.col("_actual"))
        parts.append(bad.sort("_idx").select(
            kind=pl.lit(COUNT), table=pl.lit(table), field=pl.lit(count_field), target=pl.lit(referring),
            record_index=pl.col("_idx").cast(pl.Int64), token="token", reference=pl.lit(None, pl.String),
            position=pl.lit(None, pl.Int32), stated=_as_count(pl.col(count_field)),
            actual=pl.col("_actual").cast(pl.Int64)))
    empty = pl.from_arrow(dataset_schemas()[DATASET].arrow_schema().empty_table())
    return pl.concat([empty, *[p.cast(empty.schema) for p in parts]], how="vertical")


def _as_count(column: pl.Expr) -> pl.Expr:
    """A count field as int64 (read as float64 when the source writes it as a JSON float with a fraction)."""
    as_float = column.cast(pl.Float64)
    return pl.when(as_float.is_finite()).then(as_float.round(0)).cast(pl.Int64)


def _file(table: str) -> str:
    schema = table_schemas().get(table)
    return schema.source if schema is not None else f"{table}.json"


def summary(findings: pl.DataFrame) -> list[dict]:
    """One entry per (kind, table, field) in the order found: {kind, table, field, target, count}."""
    grouped = findings.group_by("kind", "table", "field", "target", maintain_order=True).agg(count=pl.len())
    return grouped.with_columns(pl.col("kind").cast(pl.String)).to_dicts()


def manifest_entry(findings: pl.DataFrame) -> dict:
    """manifest.json `dangling`: the references that name no record and the counts that disagree, by table and
    field, with their totals; each one is a row of the `findings` dataset."""
    entries = summary(findings)
    by_kind = {kind: [{k: e[k] for k in ("table", "field", "target", "count")} for e in entries if e["kind"] == kind]
               for kind in (REFERENCE, COUNT)}
    return {"dataset": DATASET, "references": by_kind[REFERENCE], "count_mismatches": by_kind[COUNT],
            "total_references": sum(e["count"] for e in by_kind[REFERENCE]),
            "total_count_mismatches": sum(e["count"] for e in by_kind[COUNT])}


def summary_lines(findings: pl.DataFrame) -> list[str]:
    """One warning line per table and field, for the manifest's `warnings` and the terminal."""
    lines = []
    for e in summary(findings):
        n, plural = e["count"], e["count"] != 1
        if e["kind"] == REFERENCE:
            what = f"{n} {e['field']} reference{'s name' if plural else ' names'} no {e['target']} record"
        else:
            what = (f"{n} record{'s' if plural else ''} whose {e['field']} is not the number of {e['target']} records "
                    f"referring to {'them' if plural else 'it'}")
        lines.append(f"{_file(e['table'])}: {what} (accepted with --allow-dangling; each is listed in {DATASET}/)")
    return lines


def warnings(findings: pl.DataFrame, limit: int = MAX_REPORTED) -> list[Finding]:
    """The findings worded as `check_integrity` words them, as warnings: at most `limit` per table and field, plus a
    count of the rest."""
    problems: list[Finding] = []
    for (table, field), rows in findings.partition_by("table", "field", as_dict=True, maintain_order=True).items():
        file = _file(table)
        for r in rows.head(limit).iter_rows(named=True):
            message = (f"{field} {echo(r['reference'])} does not resolve to a {r['target']} record" if r["kind"] == REFERENCE
                       else f"{field} is {r['stated']} but {r['actual']} {r['target']} records refer to it")
            problems.append(Finding(file, message, r["record_index"], r["token"], warning=True))
        if rows.height > limit:
            problems.append(Finding(file, f"{rows.height - limit} more like the above", omitted=rows.height - limit,
                                    warning=True))
    return problems
