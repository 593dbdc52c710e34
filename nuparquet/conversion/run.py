"""Build every registered dataset (`registry.BUILDERS`) into a conversion's output directory.

"scenes" builders run batch by batch (scenes in name order); each result is cast to its schema and written on
a second thread while the next batch is built (Parquet encoding releases the GIL; one write in flight keeps
memory at about two batches). Then the "whole" builders run. Returns the manifest entries of what was built
and the reasons for what was skipped.
"""

from __future__ import annotations

from collections.abc import Mapping
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import polars as pl
import pyarrow as pa

from nuparquet.conversion import lookups
from nuparquet.conversion.builders.common import reference_poses, samples
from nuparquet.conversion.builder import BuildContext, Builder, BuildResult, SceneBatch, WrittenParts
from nuparquet.conversion.write import DatasetWriter
from nuparquet.schemas import Schema, dataset_schemas, fingerprint

# Source tables split by scene batch for the "scenes" builders (their rows belong to one sample); each batch also
# gets the ego_pose rows its sample_data names.
PER_SAMPLE_TABLES = ("sample", "sample_data", "sample_annotation")


def build_datasets(ctx: BuildContext, builders: tuple[Builder, ...]) -> tuple[dict[str, dict], dict[str, str]]:
    """Run `builders` into `ctx.out`: ({dataset: manifest entry}, {builder name: reason skipped})."""
    active, skipped = _select(ctx, builders)
    writers = _Writers(ctx)
    try:
        scene_builders = [b for b in active if b.scope == "scenes"]
        if scene_builders:
            for batch in _batches(ctx):
                for builder in scene_builders:
                    if ctx.reporter:
                        ctx.reporter.note(f"{builder.name}, scene batch {batch.index + 1}")
                    for name, frame in _named(builder, builder.build(ctx, batch)):
                        writers.write(builder, name, frame, batch.index)
                if ctx.reporter:
                    ctx.reporter.advance(step=f"scene batch {batch.index + 1}")
        writers.close()
        for builder in (b for b in active if b.scope == "whole"):
            if ctx.reporter:
                ctx.reporter.advance(step=builder.name)
            for name, frame in _named(builder, builder.build(ctx)):
                writers.write(builder, name, frame, 0)
            writers.close()
    finally:
        writers.shutdown()
    return writers.entries, skipped


def count_steps(ctx: BuildContext, builders: tuple[Builder, ...]) -> int:
    """Progress units `build_datasets` reports, all of them, before it starts (the bar's total never grows): one
    per scene batch (and the batch of rows of no scene, when there are any), one per "whole" builder it will run
    and the units those report themselves (`Builder.units`)."""
    active, _ = _select(ctx, builders)
    batches = 0
    if any(b.scope == "scenes" for b in active):  # (a format without scenes, nuImages, has only "whole" builders)
        batches = -(-ctx.tables["scene"].height // ctx.options.scenes_per_batch) + _has_orphans(ctx)
    return batches + sum(1 + (b.units(ctx) if b.units else 0) for b in active if b.scope == "whole")


def _has_orphans(ctx: BuildContext) -> bool:
    """Rows of the per-sample tables that belong to no scene (`_batches` gives them a last batch of their own)."""
    if not ctx.options.allow_dangling:  # the integrity check refused every sample or scene reference that dangles
        return False
    batch_of = lookups.scene_batches(ctx.tables, samples(ctx), ctx.options.scenes_per_batch)
    for table in PER_SAMPLE_TABLES:
        key = "token" if table == "sample" else "sample_token"
        rows = ctx.tables[table].select(key).join(batch_of.rename({"sample_token": key}), on=key, how="left")
        if rows["_batch"].null_count():
            return True
    return False


def _select(ctx: BuildContext, builders: tuple[Builder, ...]) -> tuple[list[Builder], dict[str, str]]:
    active, skipped = [], {}
    for builder in builders:
        reason = builder.wanted(ctx)
        if reason is None:
            missing = [n for n in builder.needs if n in skipped or n not in {b.name for b in active}]
            reason = f"needs {', '.join(missing)}, not built" if missing else None
        if reason is None:
            active.append(builder)
        else:
            skipped[builder.name] = reason
    return active, skipped


def _batches(ctx: BuildContext):
    """`SceneBatch`es in scene-name order. Each batch gathers its rows of the per-sample tables (and the ego poses
    its sample_data names) from the whole tables: one copy of a batch at a time, never a second copy of a table
    (a join or `partition_by` would hold one: ~1 GB of sample_data at trainval scale)."""
    batch_of = lookups.scene_batches(ctx.tables, samples(ctx), ctx.options.scenes_per_batch)
    reference_poses(ctx)  # reads the whole sample_data: computed before that table is released below
    positions = {}
    for table in PER_SAMPLE_TABLES:
        key = "token" if table == "sample" else "sample_token"
        ids = (ctx.tables[table].select(pl.col(key).alias("sample_token"))
               .join(batch_of, on="sample_token", how="left", maintain_order="left")["_batch"])
        positions[table] = _rows_by_batch(ids.fill_null(-1).to_numpy())
    poses = ctx.tables["ego_pose"]
    pose_of = (ctx.tables["sample_data"].select(pl.col("ego_pose_token").alias("token"))
               .join(poses.select("token").with_row_index("_row"), on="token", how="left", maintain_order="left")
               ["_row"].fill_null(-1).to_numpy().astype(np.int64))
    tables = {table: ctx.tables.pop(table) if table in ("sample_data",) else ctx.tables[table]
              for table in PER_SAMPLE_TABLES}
    ctx.tables.pop("ego_pose")  # only batches of both are needed from here on (trainval: GBs of rows)

    def batch_rows(batch: int) -> dict[str, pl.DataFrame]:
        rows = {table: tables[table][positions[table].get(batch, _NONE)] for table in PER_SAMPLE_TABLES}
        named = pose_of[positions["sample_data"].get(batch, _NONE)]
        rows["ego_pose"] = poses[np.unique(named[named >= 0])]
        return rows

    scene_batch = (ctx.tables["scene"].select(pl.col("token").alias("scene_token"), "name").sort("name", "scene_token")
                   .with_columns(_batch=pl.int_range(pl.len()) // ctx.options.scenes_per_batch))
    n_batches = -(-scene_batch.height // ctx.options.scenes_per_batch)
    for index in range(n_batches):
        scenes = scene_batch.filter(pl.col("_batch") == index)["scene_token"].to_list()
        yield SceneBatch(index, scenes, batch_rows(index))
    # Rows of no scene (their sample or its scene is absent: only `--allow-dangling` lets such input through) are
    # kept, as a last batch of their own, after every scene.
    if any(-1 in positions[table] for table in PER_SAMPLE_TABLES):  # counted by `count_steps` (`_has_orphans`)
        yield SceneBatch(n_batches, [], batch_rows(-1))


_NONE = np.zeros(0, np.int64)


def _rows_by_batch(batch_ids: np.ndarray) -> dict[int, np.ndarray]:
    """{batch id: positions of its rows, in row order} (-1: rows of no batch)."""
    order = np.argsort(batch_ids, kind="stable")
    values, starts = np.unique(batch_ids[order], return_index=True)
    bounds = [*starts.tolist(), len(order)]
    return {int(v): order[bounds[i]:bounds[i + 1]] for i, v in enumerate(values)}


def _named(builder: Builder, result: BuildResult) -> list[tuple[str, pl.DataFrame | pa.Table]]:
    if isinstance(result, Mapping):
        return list(result.items())
    return [(builder.name, result)]


class _Writers:
    """One DatasetWriter per (dataset, part), written behind on a second thread."""

    def __init__(self, ctx: BuildContext):
        self.ctx = ctx
        self.open: dict[tuple[str, int], DatasetWriter] = {}
        self.entries: dict[str, dict] = {}
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="nuparquet-write")
        self.pending: Future | None = None

    def write(self, builder: Builder, name: str, frame: pl.DataFrame | pa.Table | WrittenParts, batch: int) -> None:
        if isinstance(frame, WrittenParts):  # the builder wrote its part files itself
            self.entries[name] = {"path": name, "rows": frame.rows, "schema_fingerprint": fingerprint(frame.schema),
                                  "bytes": frame.bytes, "parts": frame.parts, **frame.extra}
            self.ctx._written[name] = name
            return
        schema = dataset_schemas()[builder.schema] if builder.schema else None
        if schema and self.ctx.options.allow_dangling:  # nulls where a join has no partner (nuparquet.sources.dangling)
            schema = schema.allowing_dangling()
        if schema and self.ctx.nullable_fields:  # a format without those facts (TruckScenes: no log)
            schema = schema.allowing_null(self.ctx.nullable_fields)
        table = to_schema(frame, schema) if schema else _to_arrow(frame)
        part = batch if builder.parts == "per_batch" else 0
        key = (name, part)
        if key not in self.open:
            self.open[key] = DatasetWriter(self.ctx.out / name, table.schema, group_by=builder.group_by, part=part)
        self._wait()
        self.pending = self.pool.submit(self.open[key].write, table)

    def _wait(self) -> None:
        if self.pending is not None:
            self.pending.result()
            self.pending = None

    def close(self) -> None:
        """Finish every open file and record the datasets in the manifest entries."""
        self._wait()
        for (name, _part), writer in self.open.items():
            size = writer.close()
            entry = self.entries.setdefault(name, {"path": name, "rows": 0, "schema_fingerprint": fingerprint(writer.schema),
                                                   "bytes": 0, "parts": 0})
            entry["rows"] += writer.rows
            entry["bytes"] += size
            entry["parts"] += 1
            self.ctx._written[name] = name
        self.open.clear()

    def shutdown(self) -> None:
        self.pool.shutdown(wait=True)
        for writer in self.open.values():
            writer.close()


def _to_arrow(frame: pl.DataFrame | pa.Table) -> pa.Table:
    return frame if isinstance(frame, pa.Table) else frame.to_arrow()


def to_schema(frame: pl.DataFrame | pa.Table, schema: Schema) -> pa.Table:
    """Exactly the columns and Arrow types of `schema` (the single definition in schemas/); a schema with `extra`
    columns keeps the frame's other columns where they stand, typed as built."""
    if isinstance(frame, pl.DataFrame):  # dictionary columns leave polars as one dictionary, never a copy per row
        categorical = [f.name for f in schema.fields if pa.types.is_dictionary(f.arrow_type) and f.name in frame.columns
                       and frame.schema[f.name] == pl.String]
        if categorical:
            frame = frame.with_columns(pl.col(categorical).cast(pl.Categorical))
    table = _to_arrow(frame)
    if not schema.extra:
        table = table.select(schema.names)
    for f in schema.fields:
        if not f.nullable and table.column(f.name).null_count:
            raise AssertionError(f"{schema.name}.{f.name} has nulls but the schema says it cannot")
    if not schema.extra:
        return table.cast(schema.arrow_schema())
    declared = schema.arrow_schema()
    fields = [declared.field(name) if name in schema.names else table.schema.field(name) for name in table.schema.names]
    return table.cast(pa.schema(fields, metadata=declared.metadata))
