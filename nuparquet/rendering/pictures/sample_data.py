"""One sample_data as a picture, as devkit `NuScenes.render_sample_data` shows it, drawn with OpenCV.

- A camera: its image with the boxes `get_sample_data(token, box_vis_level)` keeps (`overlay.build_overlay`).
- A lidar or radar: the view from above of the sample's keyframe of that channel and its previous sweeps
  (`frames.sweeps.multisweep`, `nsweeps`), in the reference lidar keyframe's frame turned into the devkit's "flat"
  ego frame (x forward to the right, y left up, `axes_limit` metres each way), with the keyframe's boxes, the ego
  at the centre, the map underneath (`underlay_map`, from the map expansion rather than the devkit's PNG mask), and
  for radar the ego-motion compensated velocities as arrows (the devkit's 6x scale, clipped at 20 m). Lidar points
  are coloured by distance as the devkit colours them (viridis over the range), or by height, intensity, lidarseg
  class or panoptic instance, with `filter_lidarseg_labels` and a class legend; lidarseg predictions come from
  `lidarseg_preds_bin_path`, and `truth_beside_preds` puts the ground truth beside them.

Returns (H, W, 3) uint8 RGB.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet import columns, geometry
from nuparquet.dataset import as_dataset
from nuparquet.errors import UsageError
from nuparquet.frames.boxes import frame_boxes
from nuparquet.frames.poses import cameras_from_frames, sensor_poses
from nuparquet.frames.sweeps import keyframe_rows, multisweep
from nuparquet.rendering import legend
from nuparquet.rendering import colorings
from nuparquet.rendering.colorings import PointColor
from nuparquet.rendering.pictures.clouds import category_names, frame_frame, lidar_cloud
from nuparquet.rendering.decode import frame_image
from nuparquet.rendering.overlay import DrawStyle, build_overlay, category_colors
from nuparquet.rendering.palette import category_rgb
from nuparquet.rendering.point_colors import (
    class_filter, intensity_levels, label_rgb, legend_classes, scalar_rgb,
)
from nuparquet.rendering.pictures.topview import PlaneView

TOP_VIEW_PX = 900  # the devkit's 9 x 9 inch figure at 100 dpi
POINT_PX = {"lidar": 2, "radar": 6}  # the devkit's scatter sizes 0.2 and 3.0, at this picture size
RADAR_VELOCITY_SCALE, RADAR_VELOCITY_CLIP_M = 6.0, 20.0  # render_sample_data's "arbitrary scaling" and clipping


def visibility_name(box_vis_level) -> str:
    """"any" / "all" / "none" from a string or the devkit's `BoxVisibility` member."""
    if type(box_vis_level) is int:  # the devkit's BoxVisibility values as plain numbers
        box_vis_level = {0: "all", 1: "any", 2: "none"}.get(box_vis_level, box_vis_level)
    name = str(getattr(box_vis_level, "name", box_vis_level)).lower()
    if name not in ("any", "all", "none"):
        raise UsageError(f"box_vis_level must be any, all or none, got {box_vis_level!r}")
    return name


def to_rgb(image_bgr: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(image_bgr[..., ::-1])


def render_sample_data(dataset_or_path, sample_data_token: str, with_anns: bool = True, box_vis_level="any",
                       axes_limit: float = 40, nsweeps: int = 1, underlay_map: bool = True,
                       use_flat_vehicle_coordinates: bool = True, *, point_color: PointColor = "depth",
                       show_lidarseg_legend: bool = False, filter_lidarseg_labels: Sequence[int] | None = None,
                       lidarseg_preds_bin_path: str | Path | None = None, radar_filters: bool = True, labels: str = "none",
                       scale: float = 1.0, size_px: int = TOP_VIEW_PX, truth_beside_preds: bool = False) -> np.ndarray:
    """The picture of sample_data `sample_data_token` (see the module docstring); the devkit's arguments, plus
    `point_color` (`point_colors.PointColor`: lidar or radar by "depth", the devkit's distance colouring (default), or
    "height"; lidar by "intensity", "lidarseg" or "panoptic"), `radar_filters` (False: every radar return, the
    devkit's `disable_filters()`), `labels` (box labels in camera images: "none", "category", "track"), `scale`
    (camera images) and `size_px` (the top view's side). The sensor files are read through the dataset's sensor reader
    (converted points, else the files under its `dataroot`)."""
    dataset = as_dataset(dataset_or_path)
    rows = frame_frame(dataset, sample_data_token)
    row = rows.row(0, named=True)
    if row["modality"] == "camera":
        image = camera_image(dataset, rows, with_anns=with_anns, visibility=visibility_name(box_vis_level),
                             labels=labels, scale=scale)
        legend.draw_caption(image, row["channel"])
        return to_rgb(image)
    if row["modality"] not in ("lidar", "radar"):
        raise UsageError(f"{row['channel']} is a {row['modality']} channel: no picture for it")
    options = dict(with_anns=with_anns, axes_limit=axes_limit, nsweeps=nsweeps, underlay_map=underlay_map,
                   flat=use_flat_vehicle_coordinates, point_color=point_color,
                   legend_on=show_lidarseg_legend, keep_classes=filter_lidarseg_labels,
                   radar_filters=radar_filters, size_px=size_px)
    image = top_view(dataset, [row], preds_path=lidarseg_preds_bin_path, **options)
    if truth_beside_preds and lidarseg_preds_bin_path is not None:
        truth = top_view(dataset, [row], preds_path=None, **options)
        image = np.concatenate([truth, np.zeros((image.shape[0], 4, 3), np.uint8), image], axis=1)
    return to_rgb(image)


def camera_image(dataset, rows: pl.DataFrame, *, with_anns: bool = True, visibility: str = "any",
                 labels: str = "none", scale: float = 1.0, annotation_tokens: Sequence[str] | None = None) -> np.ndarray:
    """(H, W, 3) BGR: the camera frame `rows` (one row) at `scale` with its boxes (`get_sample_data` at `visibility`;
    only `annotation_tokens` when given, the devkit's `selected_anntokens`). InputError for a missing image."""
    row = rows.row(0, named=True)
    size = (max(2, round(row["width"] * scale)), max(2, round(row["height"] * scale)))
    image = frame_image(dataset.sensors, row, size, scale)
    if not with_anns:
        return image
    cameras = cameras_from_frames(rows).resized_to(size)
    boxes = frame_boxes(rows, dataset.scan("annotations"), dataset.scan("tables/sample"))
    if annotation_tokens is not None:
        boxes = boxes.take(np.isin(boxes.annotation_token, list(annotation_tokens)))
    overlay = build_overlay(cameras, boxes, labels=labels, visibility=visibility)
    return overlay.draw(image, 0, DrawStyle.for_scale(scale))


def flat_pose(ref_rows: pl.DataFrame) -> tuple[np.ndarray, np.ndarray, float]:
    """(4, 4) view from the reference sensor to the devkit's flat ego frame (its `vehicle_flat_from_vehicle @
    ref_to_ego`), the ego's global (x, y) and its yaw."""
    ego_rotation = np.asarray(ref_rows["ego_rotation"][0].to_list(), np.float64)
    view = np.eye(4)
    view[:3, :3] = geometry.vehicle_flat_from_vehicle(ego_rotation)
    global_from_ego, ego_from_sensor = sensor_poses(ref_rows)
    return view @ ego_from_sensor[0], global_from_ego[0][:2, 3], float(geometry.yaw_from_quaternions(ego_rotation))


def reference_keyframe(dataset, sample_token: str) -> pl.DataFrame:
    """The sample's keyframe of the reference lidar (the devkit's `sample['data']['LIDAR_TOP']`), one full row."""
    ref_channel = dataset.channels.get("reference_lidar")
    if ref_channel is None:
        raise UsageError("the dataset has no lidar: a view from above is drawn in the reference lidar's frame")
    return frame_frame(dataset, keyframe_rows(dataset, sample_token, [ref_channel])["token"][0])


def flat_boxes(dataset, ref_rows: pl.DataFrame, *, flat: bool = True,
               annotation_tokens: Sequence[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The reference keyframe's boxes as (M, 8, 3) corners and (M,) category names: in the devkit's flat ego frame
    (`get_sample_data(..., use_flat_vehicle_coordinates=True)`: translated by -ego, turned by -yaw), or in the sensor
    frame (`flat=False`, `Dataset.boxes(at="sensor")`)."""
    if flat:
        ref = ref_rows.row(0, named=True)
        boxes = frame_boxes(ref_rows, dataset.scan("annotations"), dataset.scan("tables/sample"))
        if annotation_tokens is not None:
            boxes = boxes.take(np.isin(boxes.annotation_token, list(annotation_tokens)))
        yaw = float(geometry.yaw_from_quaternions(np.asarray(ref["ego_rotation"], np.float64)))
        c, s = np.cos(yaw), np.sin(yaw)
        flat_from_global = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        centre = (boxes.translation_m - np.asarray(ref["ego_translation"], np.float64)) @ flat_from_global.T
        rotation = flat_from_global @ geometry.rotation_matrices(boxes.rotation_wxyz)
        return geometry.box_corners(centre, boxes.size_wlh_m, rotation), boxes.category_name
    found = dataset.boxes(ref_rows, at="sensor")
    if annotation_tokens is not None:
        found = found.filter(pl.col("annotation_token").is_in(list(annotation_tokens)))
    corners = geometry.box_corners(columns.to_numpy(found["translation"], (3,)), columns.to_numpy(found["size"], (3,)),
                                   columns.to_numpy(found["rotation"], (4,)))
    return corners, found["category_name"].to_numpy()


def top_view(dataset, rows: Sequence[dict], *, with_anns: bool, axes_limit: float, nsweeps: int,
             underlay_map: bool, flat: bool, point_color: PointColor, legend_on: bool, keep_classes, radar_filters: bool, size_px: int, preds_path, caption: str | None = None) -> np.ndarray:
    """(size_px, size_px, 3) BGR: the view from above of the lidar or radar frames `rows` of one sample (several:
    the devkit's "Fused RADARs" of `render_sample`, each coloured on its own), as the module docstring says."""
    label_mode = colorings.label_mode(point_color)
    if point_color == "intensity" and rows[0]["modality"] != "lidar":
        raise UsageError(f"intensity colours lidar points; {rows[0]['channel']} is a {rows[0]['modality']}")
    first = rows[0]
    modality = first["modality"]
    if label_mode and modality != "lidar":
        raise UsageError(f"{label_mode} labels colour lidar points; {first['channel']} is a {modality}")
    if label_mode and (not first["is_key_frame"] or nsweeps != 1):
        raise UsageError(f"{label_mode} labels exist for lidar keyframes only: a keyframe and nsweeps=1")
    if underlay_map and not flat:
        raise UsageError("underlay_map needs use_flat_vehicle_coordinates (the map lies in the flat ego frame)")
    ref_rows = reference_keyframe(dataset, first["sample_token"])
    ref = ref_rows.row(0, named=True)
    view_from_ref, ego_xy, yaw = flat_pose(ref_rows) if flat else (np.eye(4), None, 0.0)
    plane = PlaneView.square(axes_limit, size_px)
    map_layers = _map_of(dataset, first) if underlay_map else None
    image = plane.map_canvas(map_layers, ego_xy, yaw) if map_layers is not None else plane.canvas()
    names = category_names(dataset) if label_mode else {}
    point_px = max(1, POINT_PX[modality] * size_px // TOP_VIEW_PX)
    shown_labels = []
    for row in rows:
        labels = None
        if label_mode:  # the devkit loads the reference keyframe's file whole: no sweeps, no close points removed
            cloud = lidar_cloud(dataset, ref, labels=label_mode, preds_path=preds_path)
            points, labels = cloud.points, cloud.labels
        else:
            points = multisweep(dataset, row["sample_token"], row["channel"], ref["channel"], nsweeps,
                                radar_filters=radar_filters).points
        xyz = np.asarray(points[:, :3], np.float64) @ view_from_ref[:3, :3].T + view_from_ref[:3, 3]
        shown = np.ones(len(points), dtype=bool)
        if label_mode:
            shown = class_filter(labels, label_mode, keep_classes, len(names))
            colours = label_rgb(labels, label_mode, names)
            shown_labels.append(labels[shown])
        elif point_color == "height":
            colours = scalar_rgb(xyz[:, 2])
        elif point_color == "intensity":
            colours = scalar_rgb(intensity_levels(points[:, 3]))
        else:  # the devkit's distance colouring, from the reference sensor, saturating at the view's corner
            distance = np.sqrt(np.sum(np.asarray(points[:, :2], np.float64) ** 2, axis=1))
            colours = scalar_rgb(np.minimum(1.0, distance / axes_limit / np.sqrt(2)))
        plane.draw_points(image, xyz[shown, :2], colours[shown], point_px)
        if modality == "radar":
            _radar_arrows(plane, image, row, ref, points, xyz, colours, view_from_ref)
    plane.draw_ego(image)
    if with_anns:  # in the view's frame already: flat, or the sensor's (whose view is the identity)
        corners, categories = flat_boxes(dataset, ref_rows, flat=flat)
        plane.draw_boxes(image, corners, category_colors(np.asarray(categories)))
    if label_mode and legend_on:
        chosen = legend_classes(np.concatenate(shown_labels), label_mode, keep_classes, names)
        legend.draw_legend(image, [(names[c], category_rgb(names[c])) for c in chosen], corner="top-right")
    if caption is None:
        caption = first["channel"] if len(rows) == 1 else f"Fused {modality}s"
    legend.draw_caption(image, caption + (" (predictions)" if preds_path is not None else ""))
    return image


def _radar_arrows(plane: PlaneView, image, row: dict, ref: dict, points, xyz, colours, view_from_ref) -> None:
    """render_sample_data's radar velocities: vx_comp, vy_comp (fields 8, 9) turned from the radar's calibration
    into the reference sensor's, vz = 0, then into the view; 6x, clipped at 20 m."""
    if points.shape[1] < 10 or not len(points):
        return
    radar_rotation = geometry.rotation_matrices(np.asarray(row["sensor_rotation"], np.float64))
    ref_rotation = geometry.rotation_matrices(np.asarray(ref["sensor_rotation"], np.float64))
    velocity = np.c_[points[:, 8:10], np.zeros(len(points))] @ radar_rotation.T @ ref_rotation
    velocity[:, 2] = 0.0
    delta = velocity @ view_from_ref[:3, :3].T * RADAR_VELOCITY_SCALE
    delta = np.clip(delta, -RADAR_VELOCITY_CLIP_M, RADAR_VELOCITY_CLIP_M)
    plane.draw_arrows(image, xyz[:, :2], delta[:, :2], colours)


def _map_of(dataset, row: dict):
    """The map expansion of the frame's location, or None when the output has no map (or no map of it)."""
    if "map/lane" not in dataset.datasets or not row.get("log_location"):
        return None
    locations = set(dataset.scan("map/lane").select("location").unique().collect()["location"].to_list())
    return dataset.map(row["log_location"]) if row["log_location"] in locations else None
