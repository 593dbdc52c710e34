"""`lidar_points/` and `radar_points/`: one row per point of the lidar `.pcd.bin` and radar `.pcd` files, with the
nuScenes-lidarseg and Panoptic nuScenes labels, converted scene by scene on a process pool.

Opt-in (`convert --sensors lidar,radar`), keyframes unless `--sweeps`. Each scene is one task
(`nuparquet.conversion.scene_points`: `SceneTask` -> `convert_scene`, a top-level function of explicit inputs) that writes one part file,
`part-{scene:05d}.parquet` (scene position in name order), committed into the temporary output by the
scale-out engine (`run_scene_tasks`: serial, local processes or Ray with `--engine ray`). Output is
byte-identical whatever `--jobs` and `--engine`.

Memory: a worker holds one row group at a time — whole frames, at most `scene_points.ROW_GROUP_ROWS` points
unless one frame is larger (a nuScenes lidar frame: ~35k points, ~1.5 MB of columns) — plus the file it is
reading; the main process holds only the frame list (one row per sensor file). So the peak is about
jobs x (one row group + one file + the interpreter, ~150-200 MB) + the frame list, independent of the number
of scenes.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import polars as pl
import pyarrow.parquet as pq

from nuparquet.conversion.builder import BuildContext, Builder, WrittenParts
from nuparquet.conversion.builders.common import samples
from nuparquet.conversion.write import parquet_part_name
from nuparquet.engine import EngineOptions, WorkUnit, move_parts, raise_failures, run_units
from nuparquet.engine.backends import default_workers
from nuparquet.problems import Problem, ProblemsFound
from nuparquet.progress import Progress
from nuparquet.conversion.scene_points import (
    LABELS, SceneSummary, SceneTask, convert_unit, layout_text, lidar_schema, radar_schema,
)


# Missing files listed by name in the manifest (all are counted); beyond this the manifest would grow by MBs.
MAX_LISTED_MISSING = 10_000


def run_scene_tasks(tasks: list[SceneTask], directory: Path, engine: EngineOptions,
                    on_done: Callable[[str], None]) -> list[SceneSummary]:
    """`convert_scene` over `tasks` on the scale-out engine (`nuparquet.engine`: in this process for one job, else
    a local process pool, or Ray with --engine ray), each scene writing into its own part folder; the parts are
    then moved into `directory` as `part-{i:05d}.parquet` in task order. Summaries in task order; a scene whose task
    raised stops the conversion with its name (UnitsFailed; with `keep_going` once every scene ran, naming each
    failed one)."""
    if engine.engine == "process" and ((engine.workers or default_workers()) <= 1 or len(tasks) <= 1):
        engine = replace(engine, engine="serial")  # one job: no worker process to start
    parts_dir = directory.parent / f".{directory.name}.parts"
    outcomes = run_units(convert_unit, [WorkUnit(task.scene_name, task) for task in tasks], parts_dir=parts_dir,
                         options=engine, on_progress=_forward(on_done), preload=("nuparquet.conversion.scene_points",))
    raise_failures(outcomes)  # keep_going (library only): the other scenes ran; every failed one is named
    move_parts(outcomes, parts_dir, directory, name=lambda index, unit, filename: parquet_part_name(index))
    shutil.rmtree(parts_dir, ignore_errors=True)
    return [SceneSummary.from_json(outcome.value) for outcome in outcomes]


def _forward(on_done: Callable[[str], None]) -> Callable[[Progress], None]:
    """The engine's progress events as one `on_done(scene name)` per finished scene."""
    seen = [0]

    def on_progress(event: Progress) -> None:
        while seen[0] < event.done:
            seen[0] += 1
            on_done(event.step)
    return on_progress


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
    # Frames of no scene (their sample or its scene is absent: only --allow-dangling lets them through) belong to no
    # scene's part file: counted and left out.
    no_scene = frames.filter(pl.col("scene_name").is_null()).height
    frames = frames.filter(pl.col("scene_name").is_not_null())
    tasks = [SceneTask(str(ctx.dataroot), str(directory / parquet_part_name(part)), part, scene, modality,
                       rows.drop("scene_name").to_dict(as_series=False), ctx.options.lidar_columns)
             for part, ((scene,), rows) in enumerate(frames.partition_by("scene_name", as_dict=True, maintain_order=True).items())]

    def done(scene: str) -> None:
        if ctx.reporter:
            ctx.reporter.advance(step=f"{name} {scene}")

    summaries = run_scene_tasks(tasks, directory, ctx.engine, done)
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
    layout = next(iter(layouts), None)
    schema = lidar_schema(layout) if modality == "lidar" else radar_schema(layout)
    written = [s for s in summaries if s.written]
    if not written:  # every file missing (or no frames): an empty, scannable dataset
        pq.write_table(schema.empty_table(), directory / parquet_part_name(0))
    if missing:
        listed = f", the first {MAX_LISTED_MISSING:,}" if len(missing) > MAX_LISTED_MISSING else ""
        ctx.warnings.append(f"{name}: {len(missing)} sensor file(s) missing, not converted (listed in manifest.json "
                            f"datasets.{name}.missing_files{listed}; --strict makes this an error)")
    extra = {"frames": frames.height - len(missing), "missing_count": len(missing),
             "missing_files": missing[:MAX_LISTED_MISSING]}  # a partial trainval download misses ~10^5 sweeps
    if no_scene:
        extra["no_scene_frames"] = no_scene
        ctx.warnings.append(f"{name}: {no_scene} frame(s) of no scene (their sample or its scene is absent) not "
                            f"converted (counted in manifest.json datasets.{name}.no_scene_frames)")
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


def _scene_tasks(modality: str) -> Callable[[BuildContext], int]:
    """`Builder.units`: the scene tasks `build_points` will run (one per scene with frames of `modality`, keyframes
    unless --sweeps), counted from the source tables before any dataset is written."""
    def units(ctx: BuildContext) -> int:
        sensors = ctx.tables["sensor"].filter(pl.col("modality") == modality)["token"]
        calibrations = ctx.tables["calibrated_sensor"].filter(pl.col("sensor_token").is_in(sensors.implode()))["token"]
        frames = ctx.tables["sample_data"].filter(pl.col("calibrated_sensor_token").is_in(calibrations.implode()))
        if not ctx.options.sweeps:
            frames = frames.filter(pl.col("is_key_frame"))
        scenes = frames.select("sample_token").join(samples(ctx).select("sample_token", "scene_name"),
                                                    on="sample_token", how="left")["scene_name"]
        return scenes.drop_nulls().n_unique()
    return units


LIDAR_BUILDER = Builder("lidar_points", build_lidar, scope="whole", schema="lidar_points", wanted=_wanted("lidar"),
                        needs=("frames",), units=_scene_tasks("lidar"))
RADAR_BUILDER = Builder("radar_points", build_radar, scope="whole", schema="radar_points", wanted=_wanted("radar"),
                        needs=("frames",), units=_scene_tasks("radar"))
