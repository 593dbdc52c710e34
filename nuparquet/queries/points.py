"""Canned queries over `lidar_points/` (convert --sensors lidar): nuScenes-lidarseg class counts, Panoptic
nuScenes instances, and lidar points per annotation box.

Class names come from `tables/category` (`index` -> `name`), never from a fixed list. Labels of frames without a
label file are null and left out. Devkit counterparts: `list_lidarseg_categories` (`lidarseg_class_counts`),
`get_sample_lidarseg_stats` (`sample_lidarseg_counts`), `list_panoptic_instances` (`panoptic_instances`,
`panoptic_instance_stats`), `points_in_box` over the keyframe cloud (`points_in_boxes`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
import polars as pl

from nuparquet import geometry
from nuparquet.queries.inputs import for_scene

if TYPE_CHECKING:
    from nuparquet.dataset import Dataset
    from nuparquet.queries.inputs import Scene

LabelSource = Literal["lidarseg", "panoptic"]
PANOPTIC_DIVISOR = 1000  # panoptic_label = category index * 1000 + instance id


def semantic_label(source: LabelSource = "lidarseg") -> pl.Expr:
    """The class index of a point: `lidarseg_label`, or `panoptic_label // 1000` (devkit panoptic_to_lidarseg)."""
    if source == "lidarseg":
        return pl.col("lidarseg_label").cast(pl.Int64)
    if source == "panoptic":
        return (pl.col("panoptic_label") // PANOPTIC_DIVISOR).cast(pl.Int64)
    raise ValueError(f"source must be 'lidarseg' or 'panoptic', got {source!r}")


def has_labels(ds: Dataset, source: LabelSource = "lidarseg") -> bool:
    """Whether `lidar_points/` holds labels of `source` (from the manifest: frames converted with a label file)."""
    entry = ds.manifest.get("datasets", {}).get("lidar_points", {})
    return bool(entry.get("labelled_frames", {}).get(source))


def _categories(ds: Dataset) -> pl.LazyFrame:
    return ds.scan("tables/category").select("index", "name").filter(pl.col("index").is_not_null())


def _labelled(ds: Dataset, scene: Scene, source: LabelSource) -> pl.LazyFrame:
    column = "lidarseg_label" if source == "lidarseg" else "panoptic_label"
    return for_scene(ds.scan("lidar_points"), scene).filter(pl.col(column).is_not_null())


def lidarseg_class_counts(ds: Dataset, *, scene: Scene = None, source: LabelSource = "lidarseg") -> pl.LazyFrame:
    """Labelled points per class, every category with an `index` (0 when it has no point): ``index, name,
    points``, by index; the numbers of devkit `list_lidarseg_categories(gt_from=source)`."""
    counts = _labelled(ds, scene, source).group_by(semantic_label(source).alias("index")).agg(pl.len().alias("points"))
    return (_categories(ds).join(counts, on="index", how="left")
            .with_columns(pl.col("points").fill_null(0).cast(pl.Int64)).sort("index"))


def sample_lidarseg_counts(ds: Dataset, *, scene: Scene = None, source: LabelSource = "lidarseg") -> pl.LazyFrame:
    """Per labelled lidar frame and class with points: ``scene_name, sample_token, sample_data_token, index,
    name, points`` (devkit `get_sample_lidarseg_stats(sample_token)` prints these for the LIDAR_TOP keyframe)."""
    counts = (_labelled(ds, scene, source)
              .group_by(pl.col("sample_data_token").cast(pl.String), semantic_label(source).alias("index"))
              .agg(pl.len().alias("points")))
    frames = ds.scan("frames").select(pl.col("token").alias("sample_data_token"), "sample_token", "scene_name")
    return (counts.join(frames, on="sample_data_token", how="left").join(_categories(ds), on="index", how="left")
            .select("scene_name", "sample_token", "sample_data_token", "index", "name", "points")
            .sort("scene_name", "sample_token", "index"))


def panoptic_instances(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """One row per panoptic instance and frame it appears in: ``scene_name, sample_data_token, timestamp, index,
    name, instance_id, points``. Instances are the labels with an instance id (> 0; ids count from 1 per scene),
    which in Panoptic nuScenes are exactly the "thing" points inside their box."""
    label = pl.col("panoptic_label")
    return (_labelled(ds, scene, "panoptic").filter(label % PANOPTIC_DIVISOR > 0)
            .group_by(pl.col("scene_name").cast(pl.String), pl.col("sample_data_token").cast(pl.String), "timestamp",
                      (label // PANOPTIC_DIVISOR).cast(pl.Int64).alias("index"),
                      (label % PANOPTIC_DIVISOR).cast(pl.Int64).alias("instance_id"))
            .agg(pl.len().alias("points"))
            .join(_categories(ds), on="index", how="left")
            .select("scene_name", "sample_data_token", "timestamp", "index", "name", "instance_id", "points")
            .sort("scene_name", "timestamp", "index", "instance_id"))


def panoptic_instance_stats(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """Per category: ``name, index, instances, frames_per_instance_mean/std, points_per_instance_mean/std``
    (ddof=0), the per-category numbers of devkit `list_panoptic_instances`; an instance is (scene, category,
    instance id), its points counted per frame."""
    rows = panoptic_instances(ds, scene=scene)
    per_instance = rows.group_by("scene_name", "index", "name", "instance_id").agg(pl.len().alias("frames"))
    frames = per_instance.group_by("index", "name").agg(
        pl.len().alias("instances"), pl.col("frames").mean().alias("frames_per_instance_mean"),
        pl.col("frames").std(ddof=0).alias("frames_per_instance_std"))
    points = rows.group_by("index").agg(pl.col("points").mean().alias("points_per_instance_mean"),
                                        pl.col("points").std(ddof=0).alias("points_per_instance_std"))
    return frames.join(points, on="index").sort("index")


def panoptic_instances_per_frame(ds: Dataset, *, scene: Scene = None) -> pl.LazyFrame:
    """``instances_per_frame_mean, instances_per_frame_std`` (ddof=0) over labelled frames with an instance
    (devkit `list_panoptic_instances`: "Per-frame number of instances")."""
    per_frame = panoptic_instances(ds, scene=scene).group_by("sample_data_token").agg(pl.len().alias("n"))
    return per_frame.select(pl.col("n").mean().alias("instances_per_frame_mean"),
                            pl.col("n").std(ddof=0).alias("instances_per_frame_std"))


def points_in_boxes(ds: Dataset, *, scene: Scene = None, channel: str | None = None) -> pl.DataFrame:
    """Lidar points inside each annotation box in its sample's keyframe cloud of `channel` (default: the
    reference lidar): ``annotation_token, sample_data_token, category_name, points_in_box, num_lidar_pts``.

    As devkit `points_in_box(box, cloud[:3])` with the box from `get_sample_data` (moved into the sensor frame
    with the keyframe's own ego pose); vectorised over boxes and points, one frame at a time (`ds.points`
    reads only that frame's row groups). On synthetic data it equals `num_lidar_pts`.
    """
    from nuparquet.geometry import Cameras
    from nuparquet.frames.boxes import frame_boxes
    from nuparquet.frames.projection import boxes_in_cameras
    from nuparquet.frames.poses import sensor_poses

    channel = channel or ds.channels["reference_lidar"]
    frames = (for_scene(ds.scan("frames"), scene)
              .filter((pl.col("channel").cast(pl.String) == channel) & pl.col("is_key_frame"))
              .sort("scene_name", "timestamp").collect())
    annotations = for_scene(ds.scan("annotations"), scene)
    boxes = frame_boxes(frames, annotations, ds.scan("tables/sample"))
    global_from_ego, ego_from_sensor = sensor_poses(frames)
    sensors = Cameras.from_poses(global_from_ego, ego_from_sensor, np.tile(np.eye(3), (frames.height, 1, 1)),
                                 np.zeros((frames.height, 2)))
    corners = boxes_in_cameras(sensors, boxes).corners_camera_m  # (M, 8, 3) sensor frame
    counts = np.zeros(boxes.frame_index.size, dtype=np.int64)
    tokens = frames["token"].to_list()
    for frame in np.unique(boxes.frame_index):
        rows = np.flatnonzero(boxes.frame_index == frame)
        cloud = ds.points(tokens[frame])[:, :3]
        counts[rows] = geometry.count_points_in_boxes(corners[rows], cloud)
    result = pl.DataFrame({"annotation_token": boxes.annotation_token, "sample_data_token": boxes.frame_token,
                           "category_name": boxes.category_name, "points_in_box": counts})
    num_pts = annotations.select(pl.col("token").alias("annotation_token"), "num_lidar_pts").collect()
    return result.join(num_pts, on="annotation_token", how="left")
