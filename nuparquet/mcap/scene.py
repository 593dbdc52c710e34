"""The rows one scene's MCAP file is made of, read in one go: every frame of every channel (keyframes and sweeps),
the annotations, the samples and the scene's own row; and the scene's CAN bus messages.

Four lazy scans collected together (`pl.collect_all`); the scene filter is pushed into each scan, so polars reads
only the row groups of that scene.
"""

from __future__ import annotations

from dataclasses import dataclass

import polars as pl

from nuparquet.errors import UsageError
from nuparquet.frames.boxes import ANNOTATION_COLUMNS

FRAME_COLUMNS = ("token", "sample_token", "channel", "modality", "timestamp", "is_key_frame", "filename", "width",
                 "height", "ego_translation", "ego_rotation", "sensor_translation", "sensor_rotation",
                 "camera_intrinsic", "global_from_ego", "ego_from_sensor")
SAMPLE_COLUMNS = ("token", "timestamp", "prev", "scene_token")
CAN_BUS_PREFIX = "can_bus/"


@dataclass(frozen=True)
class SceneRows:
    """frames: every sample_data of the scene (channel and modality as strings), sorted by timestamp then channel;
    annotations, samples: the scene's; scene: its row of `scenes` as a dict."""

    name: str
    frames: pl.DataFrame
    annotations: pl.DataFrame
    samples: pl.DataFrame
    scene: dict


def load_scene(dataset, scene: str) -> SceneRows:
    """The rows of `scene`. Raises UsageError for an unknown scene (listing the valid names)."""
    in_scene = pl.col("scene_name") == scene
    frames = (dataset.scan("frames").filter(in_scene).select(FRAME_COLUMNS)
              .with_columns(pl.col("channel").cast(pl.String), pl.col("modality").cast(pl.String))
              .sort("timestamp", "channel", "token"))
    annotations = dataset.scan("annotations").filter(in_scene).select(ANNOTATION_COLUMNS)
    scene_row = dataset.scan("scenes").filter(pl.col("name") == scene)
    samples = (dataset.scan("tables/sample").join(scene_row.select(pl.col("token").alias("scene_token")),
                                                  on="scene_token", how="semi").select(SAMPLE_COLUMNS))
    frames_df, annotations_df, samples_df, scene_df = pl.collect_all([frames, annotations, samples, scene_row])
    if scene_df.height == 0:
        names = sorted(dataset.scan("scenes").select("name").collect()["name"].to_list())
        raise UsageError(f"unknown scene {scene!r}; valid scenes: {', '.join(names) or '(none)'}")
    return SceneRows(scene, frames_df, annotations_df, samples_df, scene_df.row(0, named=True))


def can_bus_messages(dataset, scene: str) -> dict[str, pl.DataFrame]:
    """{message name: the scene's messages sorted by utime} for every CAN bus message dataset (`can_bus/<name>` with
    a `utime` column: not `meta` or `route`), without the scene_name column; empty when not converted."""
    names = [name for name in dataset.datasets if name.startswith(CAN_BUS_PREFIX)]
    scans = {}
    for name in names:
        lazy = dataset.scan(name)
        if "utime" in lazy.collect_schema().names():
            scans[name.removeprefix(CAN_BUS_PREFIX)] = (lazy.filter(pl.col("scene_name") == scene)
                                                        .drop("scene_name").sort("utime", maintain_order=True))
    return dict(zip(scans, pl.collect_all(list(scans.values())))) if scans else {}
