"""The engine task of a report's scene page: a few keyframe renderings and the CAN bus plots of one scene, written
into the unit's part folder (`nuparquet.engine`), committed into `DIR/scenes/<scene>/` by the report.

The renderings are the one-scene renderer's own frames (`render`, --frames-dir: the default camera with its boxes
and, when the dataset has a lidar, the reference lidar's points), `stills` of them kept, evenly spaced over the
scene's keyframes; the plots are `rendering.charts.plot_can_speed` and `plot_steering`.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from nuparquet.engine import WorkUnit
from nuparquet.errors import NuparquetError

STILL_SCALE = 0.5


def evenly_spaced(count: int, wanted: int) -> list[int]:
    """`wanted` indices of 0..count-1 spread evenly, first and last included (all of them if fewer)."""
    if count <= wanted:
        return list(range(count))
    return sorted({int(round(i)) for i in np.linspace(0, count - 1, wanted)})


def scene_assets(unit: WorkUnit, part: Path) -> dict:
    """`unit.args`: (dataset root, storage options, {"stills", "camera", "lidar", "can_bus", "dataroot"}).
    Returns {"stills": [[file, keyframe index, keyframes]], "plots": [file], "stills_error": str | None}."""
    from nuparquet.dataset import open_dataset
    from nuparquet.rendering.options import RenderOptions
    from nuparquet.rendering.pipeline import render

    root, storage_options, wanted = unit.args
    dataset = open_dataset(root, storage_options=storage_options)
    result: dict = {"stills": [], "plots": [], "stills_error": None}
    if wanted["stills"] and wanted["camera"]:
        frames_dir = part / "frames"
        try:
            render(dataset, unit.name, RenderOptions(channel=wanted["camera"], lidar=wanted["lidar"],
                                                     scale=STILL_SCALE, frames_dir=frames_dir, frame_format="jpg",
                                                     dataroot=wanted["dataroot"]))
            frames = sorted(frames_dir.glob("*.jpg"))
            for k, index in enumerate(evenly_spaced(len(frames), wanted["stills"])):
                name = f"still-{k}.jpg"
                frames[index].rename(part / name)
                result["stills"].append([name, index, len(frames)])
        except NuparquetError as exc:  # no image of this scene could be drawn: the page says so
            result["stills_error"] = str(exc)
        shutil.rmtree(frames_dir, ignore_errors=True)
    if wanted["can_bus"]:
        import polars as pl

        from nuparquet.rendering import charts as plots
        from nuparquet.queries import can_bus

        speeds, steering = pl.collect_all([can_bus.speed_over_time(dataset, scene=unit.name),
                                           can_bus.steering_over_time(dataset, scene=unit.name)])
        if speeds.filter(pl.col("source") != "ego_pose").height or steering.height:
            plots.plot_can_speed(speeds, part / "can_speed.png", scene=unit.name)
            plots.plot_steering(steering, part / "steering.png", scene=unit.name)
            result["plots"] = ["can_speed.png", "steering.png"]
    return result
