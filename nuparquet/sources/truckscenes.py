"""The fourteen JSON tables of a MAN TruckScenes version folder (`truckscenes.TruckScenes`' tables), read exactly
and checked.

TruckScenes is nuScenes-shaped with differences: no `log` and no `map` table (`scene.log_token` is always ""),
`ego_motion_cabin` and `ego_motion_chassis` tables, a `weather_annotation` table from v1.1 on (the devkit loads
an empty one when the file is absent) that each scene names by `weather_annotation_token`, and its own
taxonomy. The eleven tables it shares with nuScenes and `scene` are read by nuScenes' typed reader, with nuScenes' schemas
and `schemas/truckscenes/tables/scene.json` (`schemas()` puts the two together). The ego-motion tables (scalar
numbers, which that reader does not type) are typed by inference and held against their schemas as nuImages'
tables are (`sources.nuimages.type_problems`: a field missing, null or of another JSON type is refused, naming
the file, the field and the record). `weather_annotation`, whose fields the devkit does not name, and any other
JSON file of the folder are typed by inference. All of it exactly reversible: `export-json` writes every file
back byte for byte.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable

import polars as pl

from nuparquet.problems import MAX_REPORTED, Problem, echo
from nuparquet.schemas import Schema, family_table_schemas, table_schemas
from nuparquet.sources.integrity import check_integrity
from nuparquet.sources.nuimages import type_problems
from nuparquet.sources.tables import ReadResult, SourceTable, read_extra_table, read_table, version_dir

FAMILY = "truckscenes"
WEATHER = "weather_annotation"
# nuScenes tables TruckScenes has none of (its devkit loads neither; lidarseg and panoptic are nuScenes' own).
NOT_IN_TRUCKSCENES = ("log", "map", "lidarseg", "panoptic")
# What tells a TruckScenes version folder apart: tables no nuScenes-format dataset has.
MARKERS = ("ego_motion_cabin.json", "ego_motion_chassis.json")
INFERRED = ("ego_motion_cabin", "ego_motion_chassis")  # declared, but typed by inference (scalar floats)
# Columns of the derived datasets that come from the log: null in a TruckScenes conversion.
LOG_COLUMNS = ("log_location", "logfile", "vehicle", "date_captured")


def schemas() -> dict[str, Schema]:
    """The thirteen tables with a schema: nuScenes' shared ones, then TruckScenes' own (scene replaced)."""
    shared = {name: s for name, s in table_schemas().items() if name not in NOT_IN_TRUCKSCENES}
    return shared | family_table_schemas(FAMILY)


def looks_like(folder: Path) -> bool:
    """A version folder of TruckScenes: its ego-motion tables."""
    return all((folder / name).is_file() for name in MARKERS)


def read_truckscenes_tables(dataroot: Path | str, version: str, *, on_table: Callable[[str], None] | None = None,
                            finish: Callable[[SourceTable], None] | None = None) -> ReadResult:
    """Every JSON table of `dataroot/version`: the thirteen with a schema (a missing one is a problem), then
    `weather_annotation` and any other JSON file (typed by inference). Problems are collected, not raised;
    `finish(table)` runs on each table read without problems (as `sources.tables.read_tables`)."""
    folder = version_dir(dataroot, version)
    tables: dict[str, SourceTable] = {}
    problems: list[Problem] = []
    files: dict[str, dict] = {}
    declared = schemas()

    def note(path: Path) -> None:
        stat = path.stat()
        files[path.name] = {"bytes": stat.st_size, "mtime": stat.st_mtime}

    for name, schema in declared.items():
        if on_table:
            on_table(name)
        path = folder / schema.source
        if not path.is_file():
            problems.append(Problem(schema.source, f"table {name} is missing (expected {path})"))
            continue
        note(path)
        if name in INFERRED:
            table, found = read_extra_table(path)
            if table is not None and table.table.num_rows == 0:  # `[]`: no record to infer the columns from
                table = replace(table, table=schema.arrow_schema().empty_table())
            found = found or type_problems(table, schema)
        else:
            table, found = read_table(path, schema)
        problems += found
        if table is not None:
            if finish is not None:
                finish(table)
            tables[name] = table
    known = {s.source for s in declared.values()}
    for path in sorted(p for p in folder.glob("*.json") if p.name not in known):
        if on_table:
            on_table(path.stem)
        note(path)
        table, found = read_extra_table(path)
        problems += found
        if table is not None:
            if finish is not None:
                finish(table)
            tables[table.name] = table
    return ReadResult(tables, problems, files)


def check_truckscenes(tables: dict[str, pl.DataFrame], *, references: bool = True) -> list[Problem]:
    """Every problem across the parsed tables: those nuScenes' checks find (from `schemas()`), a
    `weather_annotation` whose records lack a string token, and scene weather tokens that name no record."""
    problems = check_integrity(tables, references=references, schemas=schemas())
    weather = tables.get(WEATHER)
    if weather is not None and weather.height and weather.schema.get("token") != pl.String:
        problems.append(Problem(f"{WEATHER}.json", "field 'token' must be a string in every record (the devkit "
                                                   "indexes the table by it)", 0))
        return problems
    scenes = tables.get("scene")
    if not references or scenes is None or "weather_annotation_token" not in scenes.columns:
        return problems
    tokens = weather["token"] if weather is not None and weather.height else pl.Series([], dtype=pl.String)
    dangling = (scenes.with_row_index("_idx").filter(pl.col("weather_annotation_token").is_not_null()
                                                     & ~pl.col("weather_annotation_token").is_in(tokens.implode())))
    for row in dangling.head(MAX_REPORTED).iter_rows(named=True):
        problems.append(Problem("scene.json", f"weather_annotation_token {echo(row['weather_annotation_token'])} "
                                              f"does not resolve to a {WEATHER} record", row["_idx"], row["token"]))
    return problems
