"""A report's scene page assets, a one-scene verb run over the report's scenes by the many-scene helper
(`engine.scene_files`): a few keyframe renderings and the CAN bus plots of one scene, written into a folder
(`DIR/scenes/<scene>/` once committed).

The renderings are the one-scene renderer's own frames (`render`, --frames-dir: the default camera with its boxes
and, when the dataset has a lidar, the reference lidar's points), `stills` of them kept, evenly spaced over the
scene's keyframes; the plots are `rendering.pictures.charts.plot_can_speed` and `plot_steering`.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nuparquet.errors import NuparquetError

STILL_SCALE = 0.5


def evenly_spaced(count: int, wanted: int) -> list[int]:
    """`wanted` indices of 0..count-1 spread evenly, first and last included (all of them if fewer)."""
    if count <= wanted:
        return list(range(count))
    return sorted({int(round(i)) for i in np.linspace(0, count - 1, wanted)})


@dataclass(frozen=True)
class SceneAssetOptions:
    """What a scene page holds besides its video: `stills` keyframe renderings of `camera` (with the reference
    lidar's points when `lidar`), and the CAN bus plots when `can_bus`."""

    stills: int
    camera: str | None
    lidar: bool
    can_bus: bool


@dataclass(frozen=True)
class SceneAssets:
    """What `scene_assets` wrote: stills ([file, keyframe index, keyframes]), plots (files), and why the stills
    could not be drawn (None when they were)."""

    stills: list
    plots: list
    stills_error: str | None

    def summary_entry(self, file_name: str) -> dict:
        return {"stills": self.stills, "plots": self.plots, "stills_error": self.stills_error}


def scene_assets(dataset, scene: str, out: Path, options: SceneAssetOptions) -> SceneAssets:
    """Write the keyframe renderings and CAN bus plots of `scene` into the folder `out` (a one-scene verb, run over
    every scene of a report by `engine.scene_files`)."""
    from nuparquet.rendering.video.options import RenderOptions
    from nuparquet.rendering.video.pipeline import render

    out.mkdir(parents=True, exist_ok=True)
    stills, plot_files, stills_error = [], [], None
    if options.stills and options.camera:
        frames_dir = out / "frames"
        try:
            render(dataset, scene, None, RenderOptions(channel=options.camera, lidar=options.lidar,
                                                       scale=STILL_SCALE, frame_format="jpg"),
                   frames_dir=frames_dir)
            frames = sorted(frames_dir.glob("*.jpg"))
            for k, index in enumerate(evenly_spaced(len(frames), options.stills)):
                name = f"still-{k}.jpg"
                frames[index].rename(out / name)
                stills.append([name, index, len(frames)])
        except NuparquetError as exc:  # no image of this scene could be drawn: the page says so
            stills_error = str(exc)
        shutil.rmtree(frames_dir, ignore_errors=True)
    if options.can_bus:
        import polars as pl

        from nuparquet.rendering.pictures import charts as plots
        from nuparquet.queries import can_bus

        speeds, steering = pl.collect_all([can_bus.speed_over_time(dataset, scene=scene),
                                           can_bus.steering_over_time(dataset, scene=scene)])
        if speeds.filter(pl.col("source") != "ego_pose").height or steering.height:
            plots.plot_can_speed(speeds, out / "can_speed.png", scene=scene)
            plots.plot_steering(steering, out / "steering.png", scene=scene)
            plot_files = ["can_speed.png", "steering.png"]
    return SceneAssets(stills, plot_files, stills_error)
