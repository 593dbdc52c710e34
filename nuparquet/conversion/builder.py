"""What a dataset builder is: `Builder` (its dataset name, schema file, scope and build function), the
`BuildContext` and `SceneBatch` it is given, and `WrittenParts` for datasets it writes itself. The list of builders
is `registry.BUILDERS`; the conversion (`nuparquet/conversion/run.py`) walks it and never names a dataset.

    # nuparquet/conversion/builders/sample_can_bus.py
    def build(ctx: BuildContext, batch: SceneBatch) -> pl.DataFrame: ...
    BUILDER = Builder("sample_can_bus", build, schema="sample_can_bus", wanted=needs_folder("can_bus"))

    # nuparquet/conversion/registry.py: add `sample_can_bus.BUILDER` to BUILDERS

Scopes:
- "scenes": `build(ctx, batch)` once per batch of whole scenes (`SceneBatch`: the batch's rows of the
  per-sample tables); the results are appended in batch order, one row group per `group_by` value, into one
  file (`parts="one"`) or one `part-{i:05d}.parquet` per batch (`parts="per_batch"`, for point clouds).
- "whole": `build(ctx)` once, after every "scenes" builder; it may read what they wrote (`ctx.dataset(name)`).
A build function returns a polars DataFrame or Arrow table, or a mapping {dataset name: frame} when the
datasets are only known from the input (one per CAN bus message type, one per map layer), or `WrittenParts` for a
dataset whose part files it wrote itself into `ctx.out / name` (point clouds, written by worker processes). Build functions are
top-level functions of their explicit inputs so a process pool (or Ray) can run them.

`wanted(ctx)` returns None to build, or the reason it is skipped ("not requested", "no can_bus/ folder");
the manifest lists skipped datasets with their reasons.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Union

import polars as pl
import pyarrow as pa

if TYPE_CHECKING:
    from nuparquet.conversion.options import ConvertOptions
    from nuparquet.engine.options import EngineOptions
    from nuparquet.progress import Reporter



@dataclass(frozen=True)
class WrittenParts:
    """A build result for datasets whose part files the builder wrote itself (point clouds, written scene by
    scene by worker processes straight into `ctx.out / name`): what the manifest records. `extra` is merged
    into the dataset's manifest entry (e.g. the files that were missing)."""

    schema: pa.Schema
    rows: int
    bytes: int
    parts: int
    extra: dict = field(default_factory=dict)


Frame = Union[pl.DataFrame, pa.Table, WrittenParts]
BuildResult = Union[Frame, Mapping[str, Frame]]


@dataclass
class SceneBatch:
    """A batch of whole scenes (scenes in name order): `index` from 0, and for each per-sample source table
    (sample, sample_data, sample_annotation) the rows that belong to these scenes, and the ego_pose rows their
    sample_data names (`ctx.tables` holds neither sample_data nor ego_pose while batches run)."""

    index: int
    scene_tokens: list[str]
    rows: dict[str, pl.DataFrame]


@dataclass
class BuildContext:
    """What every build function may read: the dataroot, the typed source tables, the options, shared lookups
    (computed once, see `shared`) and the datasets already written (`dataset`)."""

    dataroot: Path
    version: str
    options: ConvertOptions
    engine: EngineOptions  # where per-scene work (the point conversion) runs
    tables: dict[str, pl.DataFrame]
    out: Path  # the temporary output root being written
    reporter: Reporter | None = None
    files: list[dict] = field(default_factory=list)  # JSON files read beyond the tables (manifest "files")
    warnings: list[str] = field(default_factory=list)  # added to the manifest's "warnings"
    nullable_fields: tuple[str, ...] = ()  # columns the source format cannot fill (`SourceFormat.nullable_fields`)
    source_format: str = "nuscenes"  # the family being converted (`SourceFormat.name`): whose split lists apply
    _shared: dict[str, Any] = field(default_factory=dict)
    _written: dict[str, str] = field(default_factory=dict)  # dataset name -> its directory under `out`

    def shared(self, key: str, compute: Callable[[], Any]) -> Any:
        """`compute()` once per conversion, by key (sample lookups, reference poses, ...)."""
        if key not in self._shared:
            self._shared[key] = compute()
        return self._shared[key]

    def written(self) -> list[str]:
        """The datasets written so far, in order."""
        return list(self._written)

    def dataset(self, name: str) -> pl.LazyFrame:
        """A lazy scan of a dataset this conversion has already written (a "scenes" builder's, for "whole" ones)."""
        if name not in self._written:
            raise KeyError(f"dataset {name!r} is not written yet (built: {', '.join(self._written) or 'none'})")
        return pl.scan_parquet(str(self.out / self._written[name] / "*.parquet"))


def always(ctx: BuildContext) -> str | None:
    return None


@dataclass(frozen=True)
class Builder:
    name: str  # the dataset's path under OUT ("frames", "can_bus/pose"); for mappings, the builder's label
    build: Callable[..., BuildResult]
    scope: Literal["scenes", "whole"] = "scenes"
    schema: str | None = None  # schemas/<schema>.json types the columns; None: typed by inference
    group_by: str | None = "scene_name"  # a new row group at each change of this (sorted) column
    parts: Literal["one", "per_batch"] = "one"
    wanted: Callable[[BuildContext], str | None] = always
    needs: tuple[str, ...] = ()  # builders whose datasets it reads (ctx.dataset): skipped when they are
    # Progress units its `build` reports itself (one per scene task, ...), counted before the builders run so the
    # bar's total is known once and never grows; None: none beyond the one the run counts per builder.
    units: Callable[[BuildContext], int] | None = None


def needs_folder(relative: str) -> Callable[[BuildContext], str | None]:
    """`wanted` for builders of an expansion folder under the dataroot (can_bus/, maps/expansion/, ...)."""
    def wanted(ctx: BuildContext) -> str | None:
        return None if (ctx.dataroot / relative).is_dir() else f"no {relative}/ folder in the dataroot"
    return wanted
