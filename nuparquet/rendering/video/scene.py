"""The render's scene query: which cameras to show, and the rows of one scene they need, read in one go.

Three lazy scans collected together (`pl.collect_all`): the scene's camera frames of the wanted channels (plus
the reference lidar's keyframes when points are drawn), its annotations and its samples. Channel names come
from the data (`Dataset.channels`), never from nuScenes' list.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import polars as pl

from nuparquet.channels import default_camera
from nuparquet.errors import UsageError
from nuparquet.frames.boxes import ANNOTATION_COLUMNS
from nuparquet.frames.poses import CAMERA_COLUMNS, MATRIX_COLUMNS
from nuparquet.rendering.video.options import ALL_CHANNELS

FRAME_COLUMNS = ("token", "sample_token", "scene_token", "channel", "timestamp", "is_key_frame", "filename",
                 *MATRIX_COLUMNS, *CAMERA_COLUMNS)
SAMPLE_COLUMNS = ("token", "timestamp", "prev", "scene_token")

Layout = tuple[tuple[str, ...], ...]


@dataclass(frozen=True)
class SceneRows:
    """The rows one render needs, collected by one query.

    cameras: camera frames of the wanted channels, sorted by channel then timestamp (channel as a string);
    annotations, samples: the scene's; lidar: keyframes of the lidar whose points are drawn into the cameras
    (else empty); bev_lidar: the reference lidar's frames a bird's-eye view follows, sorted by time (keyframes, or
    every frame with --all-frames; else empty); location: the scene's log location (None when not asked).
    """

    cameras: pl.DataFrame
    annotations: pl.DataFrame
    samples: pl.DataFrame
    lidar: pl.DataFrame
    bev_lidar: pl.DataFrame
    location: str | None = None


def cameras_to_render(dataset, channel: str | None) -> tuple[str, Layout]:
    """The channel to render as it will be reported, and the layout of its tiles (rows of camera names).

    `channel`: one camera, "all" (every camera of the dataset in `Dataset.channels["camera_layout"]`), or None
    for the default camera (`channels.default_camera`).
    """
    if channel is not None and channel != ALL_CHANNELS:
        return channel, ((channel,),)  # checked by the query (`load_scene` lists the valid names)
    facts = dataset.channels
    if channel == ALL_CHANNELS:
        layout = tuple(tuple(row) for row in facts["camera_layout"] if row)
        if not layout:
            raise UsageError("the dataset has no camera to render")
        return channel, layout
    channel = default_camera(facts["cameras"], facts["camera_layout"])
    if channel is None:
        raise UsageError("the dataset has no camera to render")
    return channel, ((channel,),)


def reference_lidar(dataset) -> str:
    """The lidar whose points are drawn (`Dataset.channels["reference_lidar"]`); UsageError without one."""
    lidar = dataset.channels.get("reference_lidar")
    if lidar is None:
        raise UsageError("--lidar: the dataset has no lidar channel")
    return lidar


def load_scene(dataset, scene: str, cameras: Sequence[str], *, all_frames: bool = False,
               lidar_channel: str | None = None, bev_channel: str | None = None,
               channel_label: str | None = None) -> SceneRows:
    """Run the render's one query for `scene` (a name the dataset holds: `Dataset.check_scenes`): frames of the
    `cameras` channels (keyframes unless `all_frames`), annotations, samples, the keyframes of `lidar_channel` if
    given, and for a bird's-eye view the frames of `bev_channel` (keyframes, or all with `all_frames`) with the
    scene's location.

    Raises:
        UsageError: cameras were asked for and no camera frame matched: the channel (`channel_label`) is not a
            camera of the scene; the message lists the valid names.
    """
    channel = pl.col("channel").cast(pl.String)
    key_frames = pl.lit(True) if all_frames else pl.col("is_key_frame")
    wanted = channel.is_in(list(cameras)) & (pl.col("modality").cast(pl.String) == "camera") & key_frames
    if lidar_channel is not None:
        wanted = wanted | ((channel == lidar_channel) & pl.col("is_key_frame"))
    if bev_channel is not None:
        wanted = wanted | ((channel == bev_channel) & key_frames)
    in_scene = pl.col("scene_name") == scene
    frames = (dataset.scan("frames").filter(in_scene).filter(wanted).select(FRAME_COLUMNS)
              .with_columns(channel))
    annotations = dataset.scan("annotations").filter(in_scene).select(ANNOTATION_COLUMNS)
    samples = (
        dataset.scan("tables/sample")
        .join(frames.select("scene_token").unique(), on="scene_token", how="semi")
        .select(SAMPLE_COLUMNS)
    )
    queries = [frames, annotations, samples]
    if bev_channel is not None:
        queries.append(dataset.scan("scenes").filter(pl.col("name") == scene).select("log_location"))
    frames_df, annotations_df, samples_df, *location_df = pl.collect_all(queries)
    is_camera = frames_df["channel"].is_in(list(cameras))
    camera_rows = frames_df.filter(is_camera).sort("channel", "timestamp", maintain_order=True)
    if cameras and camera_rows.height == 0:
        _raise_unknown_channel(dataset, scene, channel_label if channel_label is not None else ",".join(cameras))
    no_rows = frames_df.clear()
    lidar = (frames_df.filter((pl.col("channel") == lidar_channel) & pl.col("is_key_frame"))
             if lidar_channel is not None else no_rows)
    bev_lidar = (frames_df.filter((pl.col("channel") == bev_channel) & (pl.lit(all_frames) | pl.col("is_key_frame")))
                 .sort("timestamp", maintain_order=True) if bev_channel is not None else no_rows)
    location = location_df[0]["log_location"][0] if location_df and location_df[0].height else None
    return SceneRows(cameras=camera_rows, annotations=annotations_df, samples=samples_df, lidar=lidar,
                     bev_lidar=bev_lidar, location=location)


def _raise_unknown_channel(dataset, scene: str, channel: str) -> None:
    """The query found no camera frame of a scene the dataset holds: the channel is not one of its cameras."""
    channels = sorted(dataset.scan("frames").filter((pl.col("scene_name") == scene)
                                                    & (pl.col("modality").cast(pl.String) == "camera"))
                      .select(pl.col("channel").cast(pl.String)).unique().collect()["channel"].to_list())
    valid = ", ".join(channels + [ALL_CHANNELS])
    modality = (dataset.scan("frames").filter(pl.col("channel").cast(pl.String) == channel)
                .select(pl.col("modality").cast(pl.String)).head(1).collect())
    if modality.height:  # a lidar or radar: say so rather than "unknown"
        raise UsageError(f"{channel} is a {modality.item()} channel; render draws camera channels: {valid}")
    raise UsageError(f"unknown channel {channel!r} for {scene}; valid channels: {valid}")
