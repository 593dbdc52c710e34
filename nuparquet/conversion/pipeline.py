"""`nuparquet convert`: nuScenes JSON -> typed tables/ + every registered dataset (frames, annotations, scenes,
instances, ...; see `registry.py`).

    read the sources (DuckDB) -> tables/ -> validate (polars) -> registered datasets, a batch of scenes at a
    time (`run.py`) -> manifest -> rename into place

Memory: each source table exists once as Arrow (until its tables/ file is written) and then once as polars;
the per-sample datasets never exist whole, only a batch of scenes of them.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import polars as pl
import pyarrow as pa

from nuparquet.version import __version__
from nuparquet.atomic import atomic_directory, check_apart, check_target
from nuparquet.conversion.builder import BuildContext
from nuparquet.conversion.options import ConvertOptions
from nuparquet.conversion.formats import AUTO, NUSCENES, SourceFormat, detect_format
from nuparquet.conversion.registry import BUILDERS
from nuparquet.conversion.run import build_datasets, count_steps, to_schema
from nuparquet.conversion.write import utc_now, write_manifest, write_parquet
from nuparquet.engine.options import EngineOptions
from nuparquet.engine.run import check_engine
from nuparquet.errors import EnvironmentFault, UsageError
from nuparquet.format import FORMAT_NAME, FORMAT_VERSION
from nuparquet.options import resolve, split_fields
from nuparquet.problems import Problem, ProblemsFound, split_warnings
from nuparquet.progress import OnProgress, Reporter
from nuparquet.schemas import dataset_schemas, fingerprint
from nuparquet.sources import dangling, json_layout

__all__ = ["ConvertOptions", "Validation", "convert", "validate"]


@dataclass(frozen=True)
class Validation:
    """What `validate` found: `problems` (each would stop a conversion; file, record index and token named),
    `warnings` (accepted as the devkit accepts them, worth knowing) and the records read per table."""

    problems: list[Problem]
    warnings: list[Problem]
    records: dict[str, int]

    @property
    def ok(self) -> bool:
        return not self.problems


def validate(dataroot: Path | str, version: str, *, on_progress: OnProgress | None = None,
             allow_dangling: bool = False, source_format: str = AUTO) -> Validation:
    """Parse and check `dataroot/version` without converting: every problem and warning found, all at once.
    `allow_dangling`: the references that name no record and the count fields that disagree are warnings
    (`nuparquet.sources.dangling`), as `convert --allow-dangling` accepts them. `source_format`: as `convert`'s."""
    fmt = detect_format(dataroot, version, source_format)
    with Reporter(on_progress, "validate", total=fmt.steps + 1) as reporter:
        result = fmt.read(dataroot, version, on_table=lambda name: reporter.advance(step=f"read {name}"))
        reporter.advance(step="check integrity")
        tables = {name: pl.from_arrow(source.table) for name, source in result.tables.items()}
        found = result.problems + fmt.check(tables, references=not allow_dangling)
        if allow_dangling and fmt.name == "nuscenes":
            found += dangling.warnings(dangling.find(tables))
        problems, warnings = split_warnings(found)
        return Validation(problems, warnings, {name: frame.height for name, frame in tables.items()})


def convert(dataroot: Path | str, version: str, out: Path | str, options: ConvertOptions | None = None, *,
            engine: EngineOptions | None = None, on_progress: OnProgress | None = None, **fields: Any) -> dict:
    """Convert `dataroot/version` into the dataset directory `out`; returns the manifest.

    `options` (`ConvertOptions`) and `engine` (`EngineOptions`: where `--sensors` scenes run) may also be given as
    keyword fields of either (`overwrite=True`, `sensors=("lidar",)`, `workers=2`). Progress goes to `on_progress`
    (see `nuparquet.progress`). Raises ProblemsFound (naming file, record and token of each problem) if the input
    is malformed or inconsistent, UsageError for bad paths or options or an existing `out` without `overwrite`.
    """
    convert_fields, engine_fields = split_fields(fields, ConvertOptions, EngineOptions)
    opts = resolve(ConvertOptions, options, convert_fields)
    engine = resolve(EngineOptions, engine, engine_fields)
    if not version or not str(version).strip():
        raise UsageError("--version must name the version folder (e.g. v1.0-mini)")
    check_apart(out, dataroot, what="the dataroot")
    check_target(out, overwrite=opts.overwrite)
    if opts.sensors:
        check_engine(engine)  # Ray installed: say so before the tables are converted, not after
    try:
        fmt = detect_format(dataroot, version, opts.source_format)
        return _convert(dataroot, version, out, opts, engine, on_progress, fmt)
    except OSError as exc:  # the machine refused (read-only folder, full disk): the partial output is already gone
        where = str(exc.filename or out)
        if Path(where).name.startswith(f".{Path(out).name}.partial-"):  # the hidden folder is ours; name what the user gave
            where = f"cannot write {out} in {Path(out).parent}"
        raise EnvironmentFault(f"{where}: {exc.strerror or exc}") from exc


def _convert(dataroot: Path | str, version: str, out: Path | str, opts: ConvertOptions, engine: EngineOptions,
             on_progress: OnProgress | None, fmt: SourceFormat) -> dict:
    # The total is unknown while the tables are read (which tables a version folder holds, how many scenes); it is
    # set once they are, counting every unit still to come, and never changes after.
    with Reporter(on_progress, "convert") as reporter, \
            atomic_directory(Path(out), overwrite=opts.overwrite) as tmp:
        def finish(source) -> None:  # in the thread that read the table, while the other one still reads
            size = write_parquet(source.table, tmp / "tables" / source.name)
            source.finished = {"dataset": {"path": f"tables/{source.name}", "rows": source.table.num_rows,
                                           "schema_fingerprint": fingerprint(source.table.schema), "bytes": size},
                               "frame": _one_chunk(pl.from_arrow(source.table))}
            source.table = None  # the polars copy is all we need from here on

        result = fmt.read(dataroot, version, on_table=lambda name: reporter.advance(step=f"read {name}"),
                          finish=finish)
        datasets: dict[str, dict] = {}
        files: list[dict] = []
        tables: dict[str, pl.DataFrame] = {}
        for name, source in result.tables.items():
            datasets[f"tables/{name}"] = source.finished["dataset"]
            entry = {"path": f"{version}/{source.path.name}", "kind": "table", "dataset": f"tables/{name}"}
            layout = json_layout.detect(source.path)
            if layout is not None:  # export-json writes the file back byte for byte
                entry["layout"] = layout
            if source.inferred is not None:  # an extra table (T4's object_ann, ...): typed by inference
                entry |= {"kind": "table_inferred", **source.inferred}
            files.append(entry)
            tables[name] = source.finished.pop("frame")
        pa.default_memory_pool().release_unused()  # the reader's Arrow tables are gone: give their pages back
        reporter.advance(step="check integrity")
        problems, warnings = split_warnings(result.problems + fmt.check(tables, references=not opts.allow_dangling))
        if problems:
            raise ProblemsFound(problems)
        ctx = BuildContext(Path(dataroot), version, opts, engine, tables, tmp, reporter,
                           nullable_fields=fmt.nullable_fields, source_format=fmt.name)
        # every builder's units and the manifest (each table was written by the thread that read it)
        # nuScenes' builders are the registry's, read here at each run (a test may replace them)
        builders = BUILDERS if fmt.name == NUSCENES.name else fmt.builders
        reporter.set_total(reporter.done + count_steps(ctx, builders) + 1)
        findings = dangling.find(tables) if opts.allow_dangling and fmt.name == "nuscenes" else None
        if findings is not None:  # before the scene batches release sample_data
            datasets[dangling.DATASET] = _write_findings(findings, tmp)
        channels = fmt.channels(tables)
        built, skipped = build_datasets(ctx, builders)
        manifest = {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "nuparquet_version": __version__,
            "created_utc": utc_now(),
            "source": {"dataroot": str(Path(dataroot).resolve()), "version": version, "format": fmt.name,
                       "files": result.files},
            "options": _recorded_options(opts, engine),
            "datasets": datasets | built,
            "skipped": skipped,
            "channels": channels,
            "warnings": [str(w) for w in warnings] + (dangling.summary_lines(findings) if findings is not None else [])
                        + ctx.warnings,
            "files": files + ctx.files,
            "tables": {name: {"key_order": s.key_order, "float_fields": s.float_fields, "json_fields": s.json_fields,
                              **({"layouts": s.layouts} if s.layouts else {})}
                       for name, s in result.tables.items() if s.inferred is None},
        }
        if findings is not None:
            manifest["dangling"] = dangling.manifest_entry(findings)
        reporter.advance(step="write manifest")
        write_manifest(tmp, manifest)
    return manifest


def _one_chunk(frame: pl.DataFrame) -> pl.DataFrame:
    """`frame` in one chunk per column (the reader gives one per window; gathering a scene batch's rows from 80
    chunks is ~20x slower), a column at a time so that only one column is ever held twice."""
    for name in frame.columns:
        if frame[name].n_chunks() > 1:
            frame = frame.with_columns(frame.get_column(name).rechunk())
    return frame


def _recorded_options(opts: ConvertOptions, engine: EngineOptions) -> dict:
    """The options manifest.json records: the conversion's own, then where its points were converted."""
    recorded = {f.name: getattr(opts, f.name) for f in fields(opts) if f.name != "overwrite"}
    return recorded | {"jobs": engine.workers or 0, "engine": engine.engine, "ray_address": engine.ray_address}


def _write_findings(findings: pl.DataFrame, root: Path) -> dict:
    """`findings/` (schemas/findings.json) and its manifest entry."""
    table = to_schema(findings, dataset_schemas()[dangling.DATASET])
    size = write_parquet(table, root / dangling.DATASET)
    return {"path": dangling.DATASET, "rows": table.num_rows, "schema_fingerprint": fingerprint(table.schema),
            "bytes": size, "parts": 1}
