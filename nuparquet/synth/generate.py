"""`synthesize`: the generator's entry point (see the package docstring), writing one dataroot scene by scene."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from nuparquet.atomic import atomic_directory
from nuparquet.options import resolve
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
from nuparquet.synth.options import SynthOptions
from nuparquet.synth.timeline import make_timeline
from nuparquet.synth.world import build_scene

__all__ = ["synthesize"]

MAP_SIZE_PX = 64
CATEGORY_LABEL_INDEX = np.array([c.index for c in CATEGORIES])  # position in CATEGORIES -> category.json index


def synthesize(out, options: SynthOptions | None = None, *, on_progress: OnProgress | None = None,
               **fields) -> Path:
    """Write a synthetic nuScenes-format dataroot into the folder `out` and return its path.

    The options (`SynthOptions`, or its fields as keywords: `synthesize(out, scenes=2, with_images=True)`):
    scenes: number of scenes (named scene-0001, ...), spread over logs of several locations.
    samples_per_scene: keyframes per scene, 2 Hz (40 = a 20 s scene, like nuScenes).
    with_images: write the 6 camera JPEGs of every keyframe and sweep (boxes painted in category colours).
    with_lidar: write the LIDAR_TOP `.pcd.bin` and the 5 radar `.pcd` files of every keyframe and sweep.
    Without either, only the tables and maps are written (trainval scale takes minutes, not hours).
    rig: the sensor set, "nuscenes" (6 cameras, LIDAR_TOP, 5 radars) or "lyft" (7 cameras with a zoomed front
    camera, 3 lidars, no radar; `taxonomy.RIGS`).
    with_can_bus: write the CAN bus expansion (`can_bus/scene-XXXX_<message>.json`) of every scene but the last
    (a scene without CAN bus data, as some real scenes are); see `synth.can_bus`.
    wild_can_bus: the CAN bus files in the shapes real ones take beyond the regular (`synth.can_bus`, wild): late
    streams, dropped messages, a zoesensors stream, mixed-case meta keys, var_stats objects.
    profile: "regular", or "irregular" for the test cases regular data lacks (gapped tracks, hills, boxes
    just in front of a camera, clock ties, a late first camera frame, and a `<version>-test` folder with empty
    annotation tables; `synth.irregular`).
    family: "nuscenes", or "nuimages" for a nuImages dataroot (`synth.nuimages`: `scenes` logs of
    `samples_per_scene` annotated images; images always written, the nuScenes-only options ignored), or
    "truckscenes" for a MAN TruckScenes dataroot (`synth.truckscenes`: images and point files always written).
    on_progress receives a `nuparquet.progress.Progress` event per scene written (None: silent).

    The tables are written to a hidden partial beside `out/<version>` and renamed into place when complete
    (`nuparquet.atomic`); an existing `out/<version>` is replaced.
    """
    options = resolve(SynthOptions, options, fields)
    scenes, samples_per_scene, seed, version = options.scenes, options.samples_per_scene, options.seed, options.version
    dataroot = Path(out)
    dataroot.mkdir(parents=True, exist_ok=True)
    if options.family == "nuimages":  # another family's tables (synth.nuimages)
        from nuparquet.synth.nuimages import synthesize_nuimages

        return synthesize_nuimages(dataroot, scenes, samples_per_scene, seed, version)
    if options.family == "truckscenes":  # MAN TruckScenes (synth.truckscenes)
        from nuparquet.synth.truckscenes import synthesize_truckscenes

        return synthesize_truckscenes(dataroot, scenes, samples_per_scene, seed, version)
    scene_duration_s = (samples_per_scene - 1) * KEYFRAME_INTERVAL_US / 1e6
    logs = plan_logs(seed, scenes, scene_duration_s, RIGS[options.rig])
    roads: dict[str, list] = {}  # location -> the roads of its scenes (for the map expansion)
    # interrupted or failed: nothing is left that could pass for a complete version folder
    with atomic_directory(dataroot / version, overwrite=True) as partial_dir:
        _write_tables_and_files(dataroot, partial_dir, logs, seed, scenes, samples_per_scene,
                                images=options.with_images, point_clouds=options.with_lidar,
                                can_bus=options.with_can_bus, on_progress=on_progress, roads=roads, version=version,
                                irregular_profile=options.profile == "irregular", wild_can_bus=options.wild_can_bus)
        _write_maps(dataroot, sorted({log.location.name for log in logs}))
        write_map_expansions(dataroot, seed, roads, {log.location.name: log.location.drives_on_right for log in logs},
                             sorted({log.location.name for log in logs}))
    if options.profile == "irregular":
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
