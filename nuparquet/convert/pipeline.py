"""`nuparquet convert`: nuScenes JSON -> typed tables/ + every registered dataset (frames, annotations, scenes,
instances, ...; see `registry.py`).

    read the sources (DuckDB) -> tables/ -> validate (polars) -> registered datasets, a batch of scenes at a
    time (`run.py`) -> manifest -> rename into place

Memory: each source table exists once as Arrow (until its tables/ file is written) and then once as polars;
the per-sample datasets never exist whole, only a batch of scenes of them.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any

import polars as pl

from nuparquet import __version__, dangling
from nuparquet.channels import channel_facts
from nuparquet.convert.options import ConvertOptions
from nuparquet.convert.registry import BUILDERS, BuildContext
from nuparquet.convert.run import build_datasets, count_steps, to_schema
from nuparquet.convert.write import atomic_directory, check_target, utc_now, write_manifest, write_parquet
from nuparquet.format import FORMAT_NAME, FORMAT_VERSION
from nuparquet.partials import check_apart
from nuparquet.errors import EnvironmentFault
from nuparquet.problems import Problem, ProblemsFound, split_warnings
from nuparquet.progress import OnProgress, Reporter
from nuparquet.schemas import dataset_schemas, fingerprint, table_schemas
from nuparquet.sources import json_layout
from nuparquet.sources.tables import ReadResult, read_tables
from nuparquet.validate import check_integrity

__all__ = ["ConvertOptions", "convert", "validate"]


def validate(dataroot: Path | str, version: str, *, on_progress: OnProgress | None = None,
             allow_dangling: bool = False) -> tuple[ReadResult, list[Problem]]:
    """Parse and check a dataroot without converting: (parsed tables, every problem found). `allow_dangling`: the
    references that name no record and the count fields that disagree are warnings (`nuparquet.dangling`), as
    `convert --allow-dangling` accepts them."""
    with Reporter(on_progress, "validate", total=len(table_schemas()) + 1) as reporter:
        result = read_tables(dataroot, version, on_table=lambda name: reporter.advance(step=f"read {name}"))
        reporter.advance(step="check integrity")
        tables = {name: pl.from_arrow(source.table) for name, source in result.tables.items()}
        if allow_dangling:
            return result, result.problems + check_integrity(tables, references=False) + dangling.warnings(dangling.find(tables))
        return result, result.problems + check_integrity(tables)


def convert(dataroot: Path | str, version: str, out: Path | str, *, on_progress: OnProgress | None = None,
            **options: Any) -> dict:
    """Convert `dataroot/version` into the dataset directory `out`; returns the manifest.

    `options` are the fields of `ConvertOptions` (`overwrite=True`, `scenes_per_batch=5`, ...). Progress goes to
    `on_progress` (see `nuparquet.progress`). Raises ProblemsFound (naming file, record and token of each
    problem) if the input is malformed or inconsistent, UsageError for bad paths or options or an existing `out`
    without `overwrite`.
    """
    opts = ConvertOptions(version=version, out=str(out), **options)
    check_apart(out, dataroot, what="the dataroot")
    check_target(out, overwrite=opts.overwrite)
    try:
        return _convert(dataroot, version, out, opts, on_progress)
    except OSError as exc:  # the machine refused (read-only folder, full disk): the partial output is already gone
        where = str(exc.filename or out)
        if Path(where).name.startswith(f".{Path(out).name}.partial-"):  # the hidden folder is ours; name what the user gave
            where = f"cannot write {out} in {Path(out).parent}"
        raise EnvironmentFault(f"{where}: {exc.strerror or exc}") from exc


def _convert(dataroot: Path | str, version: str, out: Path | str, opts: ConvertOptions,
             on_progress: OnProgress | None) -> dict:
    with Reporter(on_progress, "convert", total=2 * len(table_schemas()) + 2) as reporter, \
            atomic_directory(Path(out), overwrite=opts.overwrite) as tmp:
        result = read_tables(dataroot, version, on_table=lambda name: reporter.advance(step=f"read {name}"))
        datasets: dict[str, dict] = {}
        files: list[dict] = []
        tables: dict[str, pl.DataFrame] = {}
        for name, source in result.tables.items():
            reporter.advance(step=f"write tables/{name}")
            size = write_parquet(source.table, tmp / "tables" / name)
            datasets[f"tables/{name}"] = {"path": f"tables/{name}", "rows": source.table.num_rows,
                                          "schema_fingerprint": fingerprint(source.table.schema), "bytes": size}
            entry = {"path": f"{version}/{source.path.name}", "kind": "table", "dataset": f"tables/{name}"}
            layout = json_layout.detect(source.path)
            if layout is not None:  # export-json writes the file back byte for byte
                entry["layout"] = layout
            if source.inferred is not None:  # an extra table (T4's object_ann, ...): typed by inference
                entry |= {"kind": "table_inferred", **source.inferred}
            files.append(entry)
            tables[name] = pl.from_arrow(source.table)
            source.table = None  # the polars copy is all we need from here on
        reporter.advance(step="check integrity")
        problems, warnings = split_warnings(result.problems + check_integrity(tables, references=not opts.allow_dangling))
        if problems:
            raise ProblemsFound(problems)
        findings = dangling.find(tables) if opts.allow_dangling else None
        if findings is not None:  # before the scene batches release sample_data
            datasets[dangling.DATASET] = _write_findings(findings, tmp)
        channels = _channel_facts(tables)
        ctx = BuildContext(Path(dataroot), version, opts, tables, tmp, reporter)
        reporter.grow(count_steps(ctx, BUILDERS))
        built, skipped = build_datasets(ctx, BUILDERS)
        manifest = {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "nuparquet_version": __version__,
            "created_utc": utc_now(),
            "source": {"dataroot": str(Path(dataroot).resolve()), "version": version, "files": result.files},
            "options": {f.name: getattr(opts, f.name) for f in fields(opts) if f.name not in ("version", "out", "overwrite")},
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


def _write_findings(findings: pl.DataFrame, root: Path) -> dict:
    """`findings/` (schemas/findings.json) and its manifest entry."""
    table = to_schema(findings, dataset_schemas()[dangling.DATASET])
    size = write_parquet(table, root / dangling.DATASET)
    return {"path": dangling.DATASET, "rows": table.num_rows, "schema_fingerprint": fingerprint(table.schema),
            "bytes": size, "parts": 1}


def _channel_facts(t: dict[str, pl.DataFrame]) -> dict:
    """The dataset's channels (`nuparquet.channels.channel_facts`): names, modalities, one calibration's yaw each."""
    sensors = t["sensor"]
    calibrations = (t["calibrated_sensor"].join(sensors.select(pl.col("token").alias("sensor_token"), "channel"),
                                                on="sensor_token")
                    .sort("channel", "token").unique("channel", keep="first", maintain_order=True))
    rotations = dict(zip(calibrations["channel"].to_list(), calibrations["rotation"].to_list()))
    return channel_facts(sensors["channel"].to_list(), sensors["modality"].to_list(), rotations)
