"""The tile source of a bird's-eye view (`render.bev.BevTile`), from the rows `render.scene.load_scene` read.

The BEV follows the reference lidar: its keyframes (or every lidar frame with --all-frames) give the ego
pose, the points and the boxes (`frame_boxes`: the devkit's `get_boxes`, interpolated between keyframes). As a
tile beside the cameras it shows, for each output time, the lidar frame nearest in time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nuparquet.frames.boxes import frame_boxes
from nuparquet.frames.poses import sensor_poses
from nuparquet.rendering.bev import BevTile, MapRaster, View, scene_extent
from nuparquet.rendering.points import CloudReader
from nuparquet.rendering.video.scene import SceneRows


def _map_layers(dataset, location: str | None):
    if location is None or "map/lane" not in dataset.datasets or dataset.is_remote:
        return None
    return dataset.map(location)


def bev_source(dataset, rows: SceneRows, dataroot: Path, view: View, *, times_us: np.ndarray | None = None,
               lidar_color: str = "depth", predictions=None, lidar_predictions=None) -> tuple[BevTile, np.ndarray]:
    """The BEV tile of a scene's rows (`load_scene` with `bev_channel`) and its output times: the lidar frames'
    own times, or `times_us` (each output then shows the lidar frame nearest in time). Points are coloured by
    height, or as `lidar_color` says (lidarseg, panoptic, intensity; labels need `lidar_points/` with them).
    `predictions` (`rendering.predictions.Predictions`) are drawn on the keyframes; `lidar_predictions`: a
    lidarseg/panoptic submission folder whose labels colour the points (`CloudReader.build`)."""
    lidar = rows.bev_lidar
    stamps = lidar["timestamp"].to_numpy()
    if times_us is None:
        times_us, frame_rows = stamps.astype(np.float64), np.arange(lidar.height)
    else:
        after = np.clip(np.searchsorted(stamps, times_us), 1, len(stamps) - 1) if len(stamps) > 1 else np.zeros(len(times_us), int)
        before = np.maximum(after - 1, 0)
        frame_rows = np.where(np.abs(stamps[after] - times_us) < np.abs(times_us - stamps[before]), after, before)
    global_from_ego, ego_from_sensor = sensor_poses(lidar)
    boxes = frame_boxes(lidar, rows.annotations, rows.samples)
    raster = MapRaster.build(_map_layers(dataset, rows.location),
                             scene_extent(global_from_ego[frame_rows][:, :2, 3], view), view.px_per_m)
    predicted, predicted_rgb = None, None
    if predictions is not None:
        from nuparquet.rendering.predictions import prediction_boxes

        predicted, predicted_rows = prediction_boxes(lidar, predictions)
        predicted_rgb = predictions.colors_rgb(predicted_rows)
    tile = BevTile(frame_rows.astype(np.int64), view, raster, global_from_ego, ego_from_sensor,
                   CloudReader.build(lidar, dataroot, dataset=dataset, color=lidar_color,
                                     predictions=lidar_predictions), boxes,
                   predictions=predicted, prediction_colors_rgb=predicted_rgb,
                   prediction_legend=tuple(predictions.legend()) if predictions is not None else (),
                   tokens=tuple(lidar["token"].to_list()), timestamps_us=stamps)
    return tile, np.asarray(times_us, dtype=np.float64)
