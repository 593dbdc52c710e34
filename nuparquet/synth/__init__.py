"""Deterministic synthetic datasets in the exact nuScenes layout (`nuparquet synth`).

`synthesize(out_dir, scenes=N)` writes a dataroot that the nuscenes-devkit and nuparquet both read:

    out_dir/<version>/{attribute,calibrated_sensor,...,visibility}.json   the 13 tables
    out_dir/maps/<map token>.png                                         tiny placeholder semantic maps
    out_dir/maps/expansion/<location>.json                               map expansion v1.3 along the roads
    out_dir/samples/<CHANNEL>/..., out_dir/sweeps/<CHANNEL>/...          with images and/or lidar

It is a producer of nuScenes JSON like any real dataset: nothing else in nuparquet depends on its internals.
Same arguments -> byte-identical tables (tokens come from a seeded generator, never from the clock).

Modules: `taxonomy` (names and calibration style), `plan` (logs, scene start times, rigs), `timeline`
(sample and sensor timestamps), `road` (centreline and speed profiles), `world` (ego motion, objects,
annotations), `tables` (JSON), `sensors` (JPEG / lidar / radar files), `rigid` (quaternions and boxes),
`tokens`.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import numpy as np

from nuparquet.errors import UsageError
from nuparquet.synth import irregular
from nuparquet.synth.plan import plan_logs
from nuparquet.synth.sensors import SceneSensors
from nuparquet.progress import OnProgress, Reporter
from nuparquet.synth.can_bus import write_scene_can_bus, yaw_of
from nuparquet.synth.map_expansion import write_map_expansions
from nuparquet.synth.tables import (
    TABLES, SceneTokens, TableWriter, frame_filenames, global_records, map_token, scene_records,
)
from nuparquet.synth import lidarseg
from nuparquet.synth.taxonomy import CATEGORIES, KEYFRAME_INTERVAL_US, RIGS
from nuparquet.synth.timeline import make_timeline
from nuparquet.synth.world import build_scene

__all__ = ["synthesize"]

MAP_SIZE_PX = 64
CATEGORY_LABEL_INDEX = np.array([c.index for c in CATEGORIES])  # position in CATEGORIES -> category.json index


def synthesize(out_dir, *, scenes: int, samples_per_scene: int = 40, with_images: bool = False,
               with_lidar: bool = False, seed: int = 0, version: str = "v1.0-synth",
               on_progress: OnProgress | None = None, rig: str = "nuscenes", with_can_bus: bool = True,
               profile: str = "regular", wild_can_bus: bool = False) -> Path:
    """Write a synthetic nuScenes-format dataroot and return its path (`out_dir`).

    scenes: number of scenes (named scene-0001, ...), spread over logs of several locations.
    samples_per_scene: keyframes per scene, 2 Hz (40 = a 20 s scene, like nuScenes).
    with_images: write the 6 camera JPEGs of every keyframe and sweep (boxes painted in category colours).
    with_lidar: write the LIDAR_TOP `.pcd.bin` and the 5 radar `.pcd` files of every keyframe and sweep.
    Without either, only the tables and maps are written (trainval scale takes minutes, not hours).
    rig: the sensor set, "nuscenes" (6 cameras, LIDAR_TOP, 5 radars) or "lyft" (7 cameras with a zoomed front
    camera, 3 lidars, no radar; `taxonomy.RIGS`).
    with_can_bus: write the CAN bus expansion (`can_bus/scene-XXXX_<message>.json`) of every scene but the last
    (a scene without CAN bus data, as some real scenes are); see `synth.can_bus`.
    on_progress: receives a `nuparquet.progress.Progress` event per scene written (None: silent).
    profile: "regular", or "irregular" for the test cases regular data lacks (gapped tracks, hills, boxes
    just in front of a camera, clock ties, a late first camera frame, and a `<version>-test` folder with empty
    annotation tables; `synth.irregular`).
    wild_can_bus: the CAN bus files in the shapes real ones take beyond the regular (`synth.can_bus`, wild): late
    streams, dropped messages, a zoesensors stream, mixed-case meta keys, var_stats objects.

    The tables are written to a temporary sibling and renamed to `out_dir/<version>` when complete; an
    existing `out_dir/<version>` is replaced.
    """
    _check_arguments(scenes, samples_per_scene, seed, version)
    if rig not in RIGS:
        raise UsageError(f"rig must be one of {', '.join(RIGS)}, got {rig!r}")
    if profile not in irregular.PROFILES:
        raise UsageError(f"profile must be one of {', '.join(irregular.PROFILES)}, got {profile!r}")
    dataroot = Path(out_dir)
    dataroot.mkdir(parents=True, exist_ok=True)
    table_dir = dataroot / version
    partial_dir = dataroot / f".{version}.partial"
    if partial_dir.exists():
        shutil.rmtree(partial_dir)
    partial_dir.mkdir()

    scene_duration_s = (samples_per_scene - 1) * KEYFRAME_INTERVAL_US / 1e6
    logs = plan_logs(seed, scenes, scene_duration_s, RIGS[rig])
    roads: dict[str, list] = {}  # location -> the roads of its scenes (for the map expansion)
    try:
        _write_tables_and_files(dataroot, partial_dir, logs, seed, scenes, samples_per_scene,
                                images=with_images, point_clouds=with_lidar, can_bus=with_can_bus,
                                on_progress=on_progress, roads=roads, version=version,
                                irregular_profile=profile == "irregular", wild_can_bus=wild_can_bus)
    except BaseException:  # interrupted or failed: leave nothing that could pass for a complete version folder
        shutil.rmtree(partial_dir, ignore_errors=True)
        raise
    _write_maps(dataroot, sorted({log.location.name for log in logs}))
    write_map_expansions(dataroot, seed, roads, {log.location.name: log.location.drives_on_right for log in logs},
                         sorted({log.location.name for log in logs}))
    if table_dir.exists():
        shutil.rmtree(table_dir)
    os.replace(partial_dir, table_dir)
    if profile == "irregular":
        irregular.write_empty_annotation_version(dataroot, version)
    return dataroot


def _write_tables_and_files(dataroot: Path, table_dir: Path, logs, seed: int, scenes: int, samples_per_scene: int,
                            *, images: bool, point_clouds: bool, can_bus: bool, on_progress: OnProgress | None,
                            roads: dict[str, list], version: str = "v1.0-synth", irregular_profile: bool = False,
                            wild_can_bus: bool = False) -> None:
    """Generate the scenes one by one (one scene in memory at a time) and stream them into the tables."""
    writers = {name: TableWriter(table_dir / f"{name}.json") for name in TABLES}
    task = "synth" + (" (with sensor files)" if images or point_clouds else "")
    reporter = Reporter(on_progress, task, total=scenes, unit="scene")
    try:
        shared = global_records(logs)
        labels = None
        if point_clouds:  # lidarseg/panoptic labels of the lidar keyframes (synth.lidarseg)
            shared["category"] = lidarseg.with_lidarseg_categories(shared["category"])
            labels = lidarseg.LabelWriter(dataroot, table_dir, version, shared["category"])
        for name, records in shared.items():
            writers[name].write_dicts(records)
        for log in logs:
            for scene_index, start_us in zip(log.scene_indices, log.scene_start_us):
                # One generator per scene: its random draws do not depend on the other scenes.
                rng = np.random.default_rng([seed, 1, scene_index])
                timeline = make_timeline(rng, start_us, samples_per_scene, log.rig.channels)
                if irregular_profile:
                    timeline = irregular.irregular_timeline(timeline, log.rig.channels, scene_index)
                world = build_scene(rng, timeline, log.location.drives_on_right)
                if irregular_profile:
                    world = irregular.irregular_world(irregular.scene_rng(seed, scene_index), world, log.rig)
                tokens = SceneTokens.draw(rng, world, len(log.rig.channels))
                roads.setdefault(log.location.name, []).append(world.road)
                filenames = frame_filenames(world, log.logfile, log.rig.channels)
                for name, records in scene_records(world, tokens, log, _scene_name(scene_index, scenes),
                                                   filenames).items():
                    writers[name].write(records)
                if can_bus and (scenes == 1 or scene_index != scenes - 1):
                    write_scene_can_bus(dataroot, _scene_name(scene_index, scenes), np.random.default_rng([seed, 2, scene_index]),
                                        world.timeline.sample_timestamp_us, world.timeline.frame_timestamp_us,
                                        world.ego_translation_m, yaw_of(world.ego_rotation), wild=wild_can_bus)
                if images or point_clouds:
                    sensors = SceneSensors(world, log.rig, seed, scene_index)
                    sensors.write(dataroot, filenames, images=images, point_clouds=point_clouds)
                    if labels is not None:
                        labels.write_scene(sensors, tokens.frame, tokens.instance, CATEGORY_LABEL_INDEX[world.instance_category])
                reporter.advance()
        if labels is not None:
            labels.close()
    finally:
        reporter.close()
        for writer in writers.values():
            writer.close()


def _check_arguments(scenes, samples_per_scene, seed, version) -> None:
    if not isinstance(scenes, (int, np.integer)) or scenes < 1:
        raise UsageError(f"scenes must be a positive integer, got {scenes!r}")
    if not isinstance(samples_per_scene, (int, np.integer)) or samples_per_scene < 1:
        raise UsageError(f"samples per scene must be a positive integer, got {samples_per_scene!r}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise UsageError(f"seed must be a non-negative integer, got {seed!r}")
    if not version or "/" in version or "\\" in version or version.startswith("."):
        raise UsageError(f"version must be a plain folder name such as v1.0-synth, got {version!r}")


def _scene_name(scene_index: int, scenes: int) -> str:
    return f"scene-{scene_index + 1:0{max(4, len(str(scenes)))}d}"


def _write_maps(dataroot: Path, locations: list[str]) -> None:
    """Tiny blank semantic-prior PNGs: the devkit asserts at start-up that every map file exists."""
    maps_dir = dataroot / "maps"
    maps_dir.mkdir(exist_ok=True)
    ok, png = cv2.imencode(".png", np.zeros((MAP_SIZE_PX, MAP_SIZE_PX), dtype=np.uint8))
    if not ok:
        raise RuntimeError("OpenCV could not encode a PNG")
    for location in locations:
        (maps_dir / f"{map_token(location)}.png").write_bytes(png.tobytes())
