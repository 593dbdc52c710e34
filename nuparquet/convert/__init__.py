"""`nuparquet convert`: nuScenes JSON -> typed tables/ + denormalised frames/annotations/scenes/instances.

    read (DuckDB) -> validate (polars) -> tables/ -> derived datasets -> manifest -> rename into place
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import polars as pl
import pyarrow as pa

from nuparquet import __version__
from nuparquet.convert import derived
from nuparquet.convert.write import atomic_directory, check_target, utc_now, write_manifest, write_parquet
from nuparquet.problems import Problem, ProblemsFound
from nuparquet.reader import ReadResult, read_tables
from nuparquet.schemas import FORMAT_VERSION, Schema, dataset_schemas, fingerprint, table_schemas
from nuparquet.validate import check_integrity

# Derived datasets whose row groups follow scene boundaries (one-scene queries prune the rest).
_GROUP_BY_SCENE = {"frames": "scene_name", "annotations": "scene_name"}


def validate(dataroot: Path | str, version: str, *, on_step: Callable[[str], None] | None = None) -> tuple[ReadResult, list[Problem]]:
    """Parse and check a dataroot without converting: (parsed tables, every problem found)."""
    result = read_tables(dataroot, version, on_table=(lambda name: on_step(f"read {name}")) if on_step else None)
    if on_step:
        on_step("check integrity")
    return result, result.problems + check_integrity(result.tables)


def convert(dataroot: Path | str, version: str, out: Path | str, *, overwrite: bool = False,
            progress: bool = True) -> dict:
    """Convert `dataroot/version` into the dataset directory `out`; returns the manifest.

    Raises ProblemsFound (naming file, record and token of each problem) if the input is malformed or
    inconsistent, UsageError for bad paths or an existing `out` without `overwrite`.
    """
    from tqdm import tqdm

    check_target(out, overwrite=overwrite)
    steps = 2 * len(table_schemas()) + 7
    bar = tqdm(total=steps, disable=not progress, unit="step", desc="convert", leave=False)

    def step(what: str) -> None:
        bar.set_postfix_str(what)
        bar.update()

    try:
        result, problems = validate(dataroot, version, on_step=step)
        if problems:
            raise ProblemsFound(problems)
        with atomic_directory(Path(out), overwrite=overwrite) as tmp:
            datasets: dict[str, dict] = {}
            for name, source in result.tables.items():
                step(f"write tables/{name}")
                datasets[f"tables/{name}"] = _write(tmp, f"tables/{name}", source.table)
            frames_in = {name: pl.from_arrow(source.table) for name, source in result.tables.items()}
            schemas = dataset_schemas()
            step("build frames")
            frames = derived.build_frames(frames_in)
            datasets["frames"] = _write(tmp, "frames", _to_schema(frames, schemas["frames"]), "scene_name")
            step("build annotations")
            annotations = derived.build_annotations(frames_in, frames)
            datasets["annotations"] = _write(tmp, "annotations", _to_schema(annotations, schemas["annotations"]), "scene_name")
            step("build scenes")
            scenes = derived.build_scenes(frames_in, frames, annotations, version)
            datasets["scenes"] = _write(tmp, "scenes", _to_schema(scenes, schemas["scenes"]))
            step("build instances")
            instances = derived.build_instances(frames_in, annotations)
            datasets["instances"] = _write(tmp, "instances", _to_schema(instances, schemas["instances"]))
            manifest = {
                "format": "nuparquet",
                "format_version": FORMAT_VERSION,
                "nuparquet_version": __version__,
                "created_utc": utc_now(),
                "source": {"dataroot": str(Path(dataroot).resolve()), "version": version, "files": result.files},
                "datasets": datasets,
                "tables": {name: {"key_order": s.key_order, "float_fields": s.float_fields, "json_fields": s.json_fields}
                           for name, s in result.tables.items()},
            }
            step("write manifest")
            write_manifest(tmp, manifest)
        return manifest
    finally:
        bar.close()


def _write(root: Path, path: str, table: pa.Table, group_by: str | None = None) -> dict:
    size = write_parquet(table, root / path, group_by=group_by)
    return {"path": path, "rows": table.num_rows, "schema_fingerprint": fingerprint(table.schema), "bytes": size}


def _to_schema(df: pl.DataFrame, schema: Schema) -> pa.Table:
    """Exactly the columns and Arrow types of `schema` (the single definition in schemas/)."""
    table = df.select(schema.names).to_arrow()
    for f in schema.fields:
        if not f.nullable and table.column(f.name).null_count:
            raise AssertionError(f"{schema.name}.{f.name} has nulls but the schema says it cannot")
    return table.cast(schema.arrow_schema())
