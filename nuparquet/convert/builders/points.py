"""`lidar_points/` and `radar_points/`: one row per point of the lidar `.pcd.bin` and radar `.pcd` files, with the
nuScenes-lidarseg and Panoptic nuScenes labels, converted scene by scene on a process pool.

Opt-in (`convert --sensors lidar,radar`), keyframes unless `--sweeps`. Each scene is one task
(`nuparquet.scene_points`: `SceneTask` -> `convert_scene`, a top-level function of explicit inputs) that writes one part file,
`part-{scene:05d}.parquet` (scene position in name order), straight into the temporary output; the only pool
is in `run_scene_tasks`, so another engine can replace it. Output is byte-identical whatever `--jobs`.

Memory: a worker holds one row group at a time — whole frames, at most `scene_points.ROW_GROUP_ROWS` points
unless one frame is larger (a nuScenes lidar frame: ~35k points, ~1.5 MB of columns) — plus the file it is
reading; the main process holds only the frame list (one row per sensor file). So the peak is about
jobs x (one row group + one file + the interpreter, ~150-200 MB) + the frame list, independent of the number
of scenes.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor

import polars as pl
import pyarrow.parquet as pq

from nuparquet.convert.registry import BuildContext, Builder, WrittenParts
from nuparquet.convert.write import part_name
from nuparquet.problems import Problem, ProblemsFound
from nuparquet.scene_points import (
    LABELS, SceneSummary, SceneTask, convert_scene, layout_text, lidar_schema, radar_schema,
)


# Missing files listed by name in the manifest (all are counted); beyond this the manifest would grow by MBs.
MAX_LISTED_MISSING = 10_000


def run_scene_tasks(tasks: list[SceneTask], jobs: int, on_done: Callable[[SceneSummary], None]) -> list[SceneSummary]:
    """`convert_scene` over `tasks` (in-process for one job, else on a process pool); summaries in task order.
    The one place that chooses how scenes run in parallel (a scale-out engine can take its place)."""
    if jobs <= 1 or len(tasks) <= 1:
        summaries = []
        for task in tasks:
            summaries.append(convert_scene(task))
            on_done(summaries[-1])
        return summaries
    # forkserver: workers fork from a clean server process that imported the task module once (a plain fork of
    # this process, which runs polars/Arrow thread pools, can deadlock; spawn re-imports in every worker).
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["nuparquet.scene_points"])
    with ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), mp_context=context) as pool:
        futures = [pool.submit(convert_scene, task) for task in tasks]
        summaries = []
        try:
            for future in futures:
                summaries.append(future.result())
                on_done(summaries[-1])
        except BaseException:  # a worker failed or Ctrl-C: do not convert the remaining scenes first
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        return summaries


def sensor_frames(ctx: BuildContext, modality: str) -> pl.DataFrame:
    """The sample_data rows of `modality` to convert (keyframes unless --sweeps), in output order, with the
    lidarseg/panoptic label file of each where the index tables name one."""
    frames = (ctx.dataset("frames").filter(pl.col("modality").cast(pl.String) == modality)
              .select("token", "scene_name", pl.col("channel").cast(pl.String), "timestamp", "is_key_frame", "filename"))
    if not ctx.options.sweeps:
        frames = frames.filter(pl.col("is_key_frame"))
    frames = frames.collect()
    for table, _column, _reader in LABELS:
        index = ctx.tables.get(table)
        if modality == "lidar" and index is not None and index.height:
            frames = frames.join(index.select(pl.col("sample_data_token").alias("token"), pl.col("filename").alias(table)),
                                 on="token", how="left")
        else:
            frames = frames.with_columns(pl.lit(None, pl.String).alias(table))
    return frames.sort("scene_name", "channel", "timestamp", "token")


def build_points(ctx: BuildContext, modality: str, name: str) -> dict[str, WrittenParts]:
    directory = ctx.out / name
    directory.mkdir(parents=True, exist_ok=True)
    frames = sensor_frames(ctx, modality)
    tasks = [SceneTask(str(ctx.dataroot), str(directory / part_name(part)), part, scene, modality,
                       rows.drop("scene_name").to_dict(as_series=False), ctx.options.lidar_columns)
             for part, ((scene,), rows) in enumerate(frames.partition_by("scene_name", as_dict=True, maintain_order=True).items())]
    if ctx.reporter:
        ctx.reporter.grow(len(tasks))

    def done(summary: SceneSummary) -> None:
        if ctx.reporter:
            ctx.reporter.advance(step=f"{name} {tasks[summary.part].scene_name}")

    summaries = run_scene_tasks(tasks, ctx.options.workers, done)
    problems = [p for s in summaries for p in s.problems]
    missing = [m for s in summaries for m in s.missing]
    layouts = {s.pcd_layout: s.pcd_file for s in summaries if s.pcd_layout is not None}
    if len(layouts) > 1:
        (first, first_file), *others = layouts.items()
        problems += [Problem(file, f"PCD fields {layout_text(layout)} differ from {first_file}'s {layout_text(first)}; "
                                   f"one {name} dataset needs one layout") for layout, file in others]
    if ctx.options.strict:
        problems += [Problem(m, "sensor file missing (--strict)") for m in missing]
    if problems:
        raise ProblemsFound(problems)
    schema = lidar_schema() if modality == "lidar" else radar_schema(next(iter(layouts), None))
    written = [s for s in summaries if s.written]
    if not written:  # every file missing (or no frames): an empty, scannable dataset
        pq.write_table(schema.empty_table(), directory / part_name(0))
    if missing:
        listed = f", the first {MAX_LISTED_MISSING:,}" if len(missing) > MAX_LISTED_MISSING else ""
        ctx.warnings.append(f"{name}: {len(missing)} sensor file(s) missing, not converted (listed in manifest.json "
                            f"datasets.{name}.missing_files{listed}; --strict makes this an error)")
    extra = {"frames": frames.height - len(missing), "missing_count": len(missing),
             "missing_files": missing[:MAX_LISTED_MISSING]}  # a partial trainval download misses ~10^5 sweeps
    if len(missing) > MAX_LISTED_MISSING:
        extra["missing_files_truncated"] = True
    if modality == "lidar":
        extra["point_columns"] = ctx.options.lidar_columns
        extra["labelled_frames"] = {table: sum(s.labelled.get(table, 0) for s in summaries) for table, _c, _r in LABELS}
    size = sum(p.stat().st_size for p in directory.glob("*.parquet"))
    return {name: WrittenParts(schema, sum(s.rows for s in summaries), size, max(len(written), 1), extra)}


def _wanted(modality: str) -> Callable[[BuildContext], str | None]:
    def wanted(ctx: BuildContext) -> str | None:
        return None if modality in ctx.options.sensors else f"not requested (--sensors {modality})"
    return wanted


def build_lidar(ctx: BuildContext) -> dict[str, WrittenParts]:
    return build_points(ctx, "lidar", "lidar_points")


def build_radar(ctx: BuildContext) -> dict[str, WrittenParts]:
    return build_points(ctx, "radar", "radar_points")


LIDAR_BUILDER = Builder("lidar_points", build_lidar, scope="whole", schema="lidar_points", wanted=_wanted("lidar"),
                        needs=("frames",))
RADAR_BUILDER = Builder("radar_points", build_radar, scope="whole", schema="radar_points", wanted=_wanted("radar"),
                        needs=("frames",))
