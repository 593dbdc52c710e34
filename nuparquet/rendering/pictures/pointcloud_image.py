"""A sample's lidar or radar points on one of its camera images, as devkit `render_pointcloud_in_image`
(`map_pointcloud_to_image`) shows them: the keyframe's whole cloud moved through its own ego pose into the camera
at the image's time (`frames.points_in_image.points_in_image`: depth above `min_dist`, one pixel inside the border),
coloured by depth (viridis over the points kept), lidar intensity (`render_intensity`), lidarseg class or panoptic
instance (the devkit's colours, `filter_lidarseg_labels` hiding the other classes, a legend, predictions from
`lidarseg_preds_bin_path`). Returns (H, W, 3) uint8 RGB.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from nuparquet.dataset import as_dataset
from nuparquet.errors import UsageError
from nuparquet.frames.points_in_image import POINT_MIN_DEPTH_M, points_in_image
from nuparquet.frames.poses import cameras_from_frames, sensor_poses
from nuparquet.frames.sweeps import frame_cloud, keyframe_rows
from nuparquet.rendering import draw, legend
from nuparquet.rendering import colorings
from nuparquet.rendering.colorings import PointColor
from nuparquet.rendering.pictures.clouds import category_names, frame_frame, lidar_cloud
from nuparquet.rendering.decode import frame_image
from nuparquet.rendering.palette import category_rgb
from nuparquet.rendering.point_colors import class_filter, intensity_levels, label_rgb, legend_classes, scalar_rgb


def dot_px(dot_size: float, scale: float) -> int:
    """The side of a drawn point for the devkit's scatter `dot_size` (points squared at its figure size)."""
    return max(1, round(0.6 * dot_size * scale))


def points_on_image(dataset, camera_rows, point_rows, *, scale: float = 1.0, dot_size: float = 5,
                    point_color: PointColor = "depth", keep_classes: Sequence[int] | None = None, legend_on: bool = False, preds_path=None,
                    min_dist: float = POINT_MIN_DEPTH_M, radar_filters: bool = True) -> np.ndarray:
    """(H, W, 3) BGR: the point frame `point_rows` (one row) drawn on the camera frame `camera_rows` (one row)."""
    camera = camera_rows.row(0, named=True)
    sensor = point_rows.row(0, named=True)
    label_mode = colorings.label_mode(point_color)
    render_intensity = point_color == "intensity"
    if point_color == "height":
        raise UsageError("points on an image are coloured by depth, intensity or labels; height is a view from above's")
    if (render_intensity or label_mode) and sensor["modality"] != "lidar":
        raise UsageError(f"intensity and labels colour lidar points; {sensor['channel']} is a {sensor['modality']}")
    if label_mode and not sensor["is_key_frame"]:
        raise UsageError(f"{label_mode} labels exist for lidar keyframes only")
    size = (max(2, round(camera["width"] * scale)), max(2, round(camera["height"] * scale)))
    image = frame_image(dataset.sensors, camera, size, scale)
    labels = None
    if sensor["modality"] == "lidar":
        cloud = lidar_cloud(dataset, sensor, labels=label_mode, preds_path=preds_path)
        points, labels = cloud.points, cloud.labels
    else:
        points, _ = frame_cloud(dataset, sensor, sensor["modality"], radar_filters)
    global_from_ego, ego_from_sensor = sensor_poses(point_rows)
    uv, depth_m, index = points_in_image(points, global_from_ego[0], ego_from_sensor[0],
                                         cameras_from_frames(camera_rows).resized_to(size), min_depth_m=min_dist)
    names = category_names(dataset) if label_mode else {}
    shown = np.ones(len(index), dtype=bool)
    if label_mode:
        colours = label_rgb(labels[index], label_mode, names)
        shown = class_filter(labels[index], label_mode, keep_classes, len(names))
    elif render_intensity:
        colours = scalar_rgb(intensity_levels(points[:, 3])[index])
    else:
        colours = scalar_rgb(depth_m)
    draw.draw_points(image, uv[shown], depth_m[shown], size_px=dot_px(dot_size, scale),
                     colors_bgr=draw.rgb_to_bgr(colours[shown]))
    if label_mode and legend_on:
        chosen = legend_classes(labels[index][shown], label_mode, keep_classes, names)
        legend.draw_legend(image, [(names[c], category_rgb(names[c])) for c in chosen], corner="top-right")
    legend.draw_caption(image, camera["channel"] + (" (predictions)" if preds_path is not None else ""))
    return image


def render_pointcloud_in_image(dataset_or_path, sample_token: str, dot_size: float = 5,
                               pointsensor_channel: str | None = None, camera_channel: str | None = None, *,
                               point_color: PointColor = "depth", filter_lidarseg_labels: Sequence[int] | None = None,
                               show_lidarseg_legend: bool = False, lidarseg_preds_bin_path: str | Path | None = None,
                               min_dist: float = POINT_MIN_DEPTH_M, scale: float = 1.0, radar_filters: bool = True) -> np.ndarray:
    """The sample's `pointsensor_channel` keyframe (default: the reference lidar) on its `camera_channel` keyframe
    image (default: the default camera), its points coloured as `point_color` says; the devkit's other arguments, plus
    `scale` (the image's) and `radar_filters`. The
    files are read through the dataset's sensor reader (its `dataroot`). See the module docstring."""
    dataset = as_dataset(dataset_or_path)
    from nuparquet.channels import default_camera

    facts = dataset.channels
    pointsensor_channel = pointsensor_channel or facts.get("reference_lidar")
    camera_channel = camera_channel or default_camera(facts["cameras"], facts["camera_layout"])
    keyframes = keyframe_rows(dataset, sample_token, [pointsensor_channel, camera_channel])
    token_of = dict(zip(keyframes["channel"].to_list(), keyframes["token"].to_list()))
    image = points_on_image(dataset, frame_frame(dataset, token_of[camera_channel]),
                            frame_frame(dataset, token_of[pointsensor_channel]), scale=scale, dot_size=dot_size,
                            point_color=point_color,
                            keep_classes=filter_lidarseg_labels, legend_on=show_lidarseg_legend,
                            preds_path=lidarseg_preds_bin_path, min_dist=min_dist, radar_filters=radar_filters)
    return np.ascontiguousarray(image[..., ::-1])
