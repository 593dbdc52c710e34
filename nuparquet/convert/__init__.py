"""`nuparquet convert`: nuScenes JSON -> typed tables/ + denormalised frames/annotations/scenes/instances.

    read (DuckDB) -> tables/ -> validate (polars) -> derived datasets, a batch of scenes at a time
    -> manifest -> rename into place

Memory: each source table exists once as Arrow (until its tables/ file is written) and then once as
polars; frames and annotations never exist whole, only a batch of scenes of them (see derived.py).
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Callable

import polars as pl
import pyarrow as pa

from nuparquet import __version__
from nuparquet.convert import derived
from nuparquet.convert.write import DatasetWriter, atomic_directory, check_target, utc_now, write_manifest, write_parquet
from nuparquet.problems import Problem, ProblemsFound
from nuparquet.reader import ReadResult, read_tables
from nuparquet.format import FORMAT_NAME, FORMAT_VERSION
from nuparquet.schemas import Schema, dataset_schemas, fingerprint, table_schemas
from nuparquet.validate import check_integrity

# Scenes per batch when building frames/annotations: ~30k frames each at nuScenes rates (~3k per scene),
# small enough to keep trainval's peak memory low, large enough that per-batch overhead is negligible.
SCENES_PER_BATCH = 10


def validate(dataroot: Path | str, version: str, *, on_step: Callable[[str], None] | None = None) -> tuple[ReadResult, list[Problem]]:
    """Parse and check a dataroot without converting: (parsed tables, every problem found)."""
    result = read_tables(dataroot, version, on_table=(lambda name: on_step(f"read {name}")) if on_step else None)
    if on_step:
        on_step("check integrity")
    tables = {name: pl.from_arrow(source.table) for name, source in result.tables.items()}
    return result, result.problems + check_integrity(tables)


def convert(dataroot: Path | str, version: str, out: Path | str, *, overwrite: bool = False,
            progress: bool = True) -> dict:
    """Convert `dataroot/version` into the dataset directory `out`; returns the manifest.

    Raises ProblemsFound (naming file, record and token of each problem) if the input is malformed or
    inconsistent, UsageError for bad paths or an existing `out` without `overwrite`.
    """
    from tqdm import tqdm

    check_target(out, overwrite=overwrite)
    bar = tqdm(total=2 * len(table_schemas()) + 4, disable=not progress, unit="step", desc="convert", leave=False)

    def step(what: str) -> None:
        bar.set_postfix_str(what)
        bar.update()

    try:
        with atomic_directory(Path(out), overwrite=overwrite) as tmp:
            result = read_tables(dataroot, version, on_table=lambda name: step(f"read {name}"))
            datasets: dict[str, dict] = {}
            tables: dict[str, pl.DataFrame] = {}
            for name, source in result.tables.items():
                step(f"write tables/{name}")
                datasets[f"tables/{name}"] = _write(tmp, f"tables/{name}", source.table)
                tables[name] = pl.from_arrow(source.table)
                source.table = None  # the polars copy is all we need from here on
            step("check integrity")
            problems = result.problems + check_integrity(tables)
            if problems:
                raise ProblemsFound(problems)
            datasets |= _write_derived(tables, tmp, version, bar if progress else None)
            manifest = {
                "format": FORMAT_NAME,
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


def _write_derived(t: dict[str, pl.DataFrame], root: Path, version: str, bar) -> dict[str, dict]:
    """frames and annotations a batch of scenes at a time, then scenes and instances from aggregates."""
    schemas = dataset_schemas()
    samples = derived.sample_lookup(t)
    references = derived.reference_poses(t, samples)
    batch_of = derived.scene_batches(t, samples, SCENES_PER_BATCH)
    # Split the two big tables by batch once; the whole tables are not needed afterwards.
    frame_parts = t.pop("sample_data").join(batch_of, on="sample_token", how="left").partition_by(
        "_batch", as_dict=True, include_key=False)
    annotation_parts = t["sample_annotation"].join(batch_of, on="sample_token", how="left").partition_by(
        "_batch", as_dict=True, include_key=False)
    batches = sorted({key[0] for key in frame_parts} | {key[0] for key in annotation_parts})
    counts, times, lengths = [], [], []
    writers = {name: DatasetWriter(root / name, schemas[name].arrow_schema(), group_by="scene_name")
               for name in ("frames", "annotations")}
    if bar is not None:
        bar.total += len(batches)
    # Parquet encoding releases the GIL: write each batch on a second thread while the next one is built,
    # one write in flight at a time so memory stays at about two batches.
    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="nuparquet-write")
    pending: Future | None = None

    def write_behind(name: str, table: pa.Table) -> None:
        nonlocal pending
        if pending is not None:
            pending.result()
        pending = pool.submit(writers[name].write, table)

    try:
        for batch in batches:
            if bar is not None:
                bar.set_postfix_str(f"frames and annotations, scene batch {batch + 1}/{len(batches)}")
                bar.update()
            part = frame_parts.pop((batch,), None)
            if part is not None:
                write_behind("frames", _to_schema(derived.build_frames(t, part, samples), schemas["frames"]))
            part = annotation_parts.pop((batch,), None)
            if part is not None:
                annotations = derived.build_annotations(t, part, samples, references)
                write_behind("annotations", _to_schema(annotations, schemas["annotations"]))
                counts.append(derived.scene_counts(annotations))
                times.append(annotations.select("token", "scene_token", "scene_name", "timestamp"))
                lengths.append(derived.path_lengths(annotations, "instance_token", "timestamp", "translation"))
        if pending is not None:
            pending.result()
        out = {name: _info(name, w.rows, w.schema, w.close()) for name, w in writers.items()}
    finally:
        pool.shutdown(wait=True)
        for w in writers.values():
            w.close()
    empty_counts = pl.DataFrame(schema={"scene_token": pl.String, "num_annotations": pl.UInt32, "num_instances": pl.UInt32})
    scenes = derived.build_scenes(t, references, pl.concat(counts) if counts else empty_counts, version)
    out["scenes"] = _write(root, "scenes", _to_schema(scenes, schemas["scenes"]))
    empty_times = pl.DataFrame(schema={"token": pl.String, "scene_token": pl.String, "scene_name": pl.String, "timestamp": pl.Int64})
    empty_lengths = pl.DataFrame(schema={"instance_token": pl.String, "_step": pl.Float64})
    instances = derived.build_instances(t, pl.concat(times) if times else empty_times,
                                        pl.concat(lengths) if lengths else empty_lengths)
    out["instances"] = _write(root, "instances", _to_schema(instances, schemas["instances"]))
    return out


def _info(path: str, rows: int, schema: pa.Schema, size: int) -> dict:
    """A dataset's manifest entry."""
    return {"path": path, "rows": rows, "schema_fingerprint": fingerprint(schema), "bytes": size}


def _write(root: Path, path: str, table: pa.Table) -> dict:
    return _info(path, table.num_rows, table.schema, write_parquet(table, root / path))


def _to_schema(df: pl.DataFrame, schema: Schema) -> pa.Table:
    """Exactly the columns and Arrow types of `schema` (the single definition in schemas/)."""
    table = df.select(schema.names).to_arrow()
    for f in schema.fields:
        if not f.nullable and table.column(f.name).null_count:
            raise AssertionError(f"{schema.name}.{f.name} has nulls but the schema says it cannot")
    return table.cast(schema.arrow_schema())
