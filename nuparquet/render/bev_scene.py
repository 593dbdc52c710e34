"""The rows a bird's-eye view needs, read in one query, and its tile source (`render.bev.BevTile`).

The BEV follows the reference lidar: its keyframes (or every lidar frame with --all-frames) give the ego
pose, the points and the boxes (`frame_boxes`: the devkit's `get_boxes`, interpolated between keyframes). As a
tile beside the cameras it shows, for each output time, the lidar frame nearest in time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import UsageError
from nuparquet.frame_boxes import ANNOTATION_COLUMNS, frame_boxes
from nuparquet.projection.frames import MATRIX_COLUMNS, sensor_poses
from nuparquet.render.bev import BevTile, MapRaster, View, scene_extent
from nuparquet.render.points import CloudReader
from nuparquet.render.scene import SAMPLE_COLUMNS, reference_lidar

LIDAR_COLUMNS = ("token", "sample_token", "scene_token", "channel", "timestamp", "is_key_frame", "filename",
                 *MATRIX_COLUMNS)


def load_bev_rows(dataset, scene: str, *, all_frames: bool) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame, str | None]:
    """(reference-lidar frames sorted by time, annotations, samples, the scene's location) of `scene`."""
    lidar_channel = reference_lidar(dataset)
    in_scene = pl.col("scene_name") == scene
    wanted = pl.col("channel").cast(pl.String) == lidar_channel
    if not all_frames:
        wanted = wanted & pl.col("is_key_frame")
    frames = (dataset.scan("frames").filter(in_scene & wanted).select(LIDAR_COLUMNS)
              .with_columns(pl.col("channel").cast(pl.String)).sort("timestamp"))
    annotations = dataset.scan("annotations").filter(in_scene).select(ANNOTATION_COLUMNS)
    samples = (dataset.scan("tables/sample").join(frames.select("scene_token").unique(), on="scene_token", how="semi")
               .select(SAMPLE_COLUMNS))
    location = dataset.scan("scenes").filter(pl.col("name") == scene).select("log_location")
    frames_df, annotations_df, samples_df, location_df = pl.collect_all([frames, annotations, samples, location])
    if frames_df.height == 0:
        scenes = sorted(dataset.scan("scenes").select("name").collect()["name"].to_list())
        if scene not in scenes:
            raise UsageError(f"unknown scene {scene!r}; valid scenes: {', '.join(scenes) or '(none)'}")
        raise UsageError(f"{scene} has no {lidar_channel} frame to centre the bird's-eye view on")
    return frames_df, annotations_df, samples_df, (location_df["log_location"][0] if location_df.height else None)


def _map_layers(dataset, location: str | None):
    if location is None or "map/lane" not in dataset.datasets or dataset.is_remote:
        return None
    from nuparquet.map.queries import MapLayers

    return MapLayers.open(Path(dataset.root), location)


def bev_source(dataset, scene: str, dataroot: Path, view: View, *, all_frames: bool,
               times_us: np.ndarray | None = None, lidar_color: str = "depth",
               predictions=None) -> tuple[BevTile, np.ndarray]:
    """The BEV tile and its output times: the lidar frames' own times, or `times_us` (each output then shows the
    lidar frame nearest in time). Points are coloured by height, or as `lidar_color` says (lidarseg, panoptic,
    intensity; labels need `lidar_points/` with them). `predictions` (`render.predictions.Predictions`) are drawn
    on the keyframes."""
    lidar, annotations, samples, location = load_bev_rows(dataset, scene, all_frames=all_frames)
    stamps = lidar["timestamp"].to_numpy()
    if times_us is None:
        times_us, rows = stamps.astype(np.float64), np.arange(lidar.height)
    else:
        after = np.clip(np.searchsorted(stamps, times_us), 1, len(stamps) - 1) if len(stamps) > 1 else np.zeros(len(times_us), int)
        before = np.maximum(after - 1, 0)
        rows = np.where(np.abs(stamps[after] - times_us) < np.abs(times_us - stamps[before]), after, before)
    global_from_ego, ego_from_sensor = sensor_poses(lidar)
    boxes = frame_boxes(lidar, annotations, samples)
    raster = MapRaster.build(_map_layers(dataset, location), scene_extent(global_from_ego[rows][:, :2, 3], view),
                             view.px_per_m)
    predicted, predicted_rgb = None, None
    if predictions is not None:
        from nuparquet.render.predictions import prediction_boxes

        predicted, predicted_rows = prediction_boxes(lidar, predictions)
        predicted_rgb = predictions.colors_rgb(predicted_rows)
    tile = BevTile(rows.astype(np.int64), view, raster, global_from_ego, ego_from_sensor,
                   CloudReader.build(lidar, dataroot, dataset=dataset, color=lidar_color), boxes,
                   predictions=predicted, prediction_colors_rgb=predicted_rgb)
    return tile, np.asarray(times_us, dtype=np.float64)
