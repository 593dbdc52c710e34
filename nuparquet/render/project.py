"""Boxes and lidar points in camera images, for many camera frames at once, exactly as nuscenes-devkit does it.

The input is rows of the converted datasets (`schemas/frames.json`, `schemas/annotations.json`, and the
`tables/sample` table), as polars DataFrames or LazyFrames:

    frames = ds.scan("frames").filter(pl.col("scene_name") == "scene-0061", pl.col("modality") == "camera")
    samples = ds.scan("tables/sample")
    annotations = ds.scan("annotations").filter(pl.col("scene_name") == "scene-0061")
    projected = project_boxes(frames, annotations, samples, visibility="any")

One polars join pairs every frame with the boxes of its sample (and, for sweeps, with the same instance's box
in the previous sample); the geometry then runs once over all (frame, box) pairs as numpy stacks. The devkit
functions this reproduces are named on each function: `NuScenes.get_boxes`, `NuScenes.get_sample_data`,
`geometry_utils.box_in_image` and `NuScenesExplorer.map_pointcloud_to_image`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Literal

import numpy as np
import polars as pl

from nuparquet import geometry

Visibility = Literal["any", "all", "none"]
VISIBILITIES: tuple[str, ...] = ("any", "all", "none")

# devkit box_in_image: a corner counts as visible only if it is more than 1 m in front of the camera, and a
# box is dropped (for ANY and ALL) unless every corner is more than 0.1 m in front.
CORNER_MIN_DEPTH_M = 1.0
BOX_MIN_DEPTH_M = 0.1
# devkit map_pointcloud_to_image: min_dist default, and the 1-pixel margin it leaves "for aesthetic reasons".
POINT_MIN_DEPTH_M = 1.0
POINT_MARGIN_PX = 1.0

_FRAME_COLUMNS = ("token", "sample_token", "timestamp", "is_key_frame")
_CAMERA_COLUMNS = (
    "ego_translation", "ego_rotation", "sensor_translation", "sensor_rotation", "camera_intrinsic", "width", "height",
)
_ANNOTATION_COLUMNS = ("token", "sample_token", "instance_token", "category_name", "translation", "size", "rotation")
_SAMPLE_COLUMNS = ("token", "timestamp", "prev")


def _lazy(frame: pl.DataFrame | pl.LazyFrame, needed: tuple[str, ...], what: str) -> pl.LazyFrame:
    lazy = frame.lazy()
    missing = [name for name in needed if name not in lazy.collect_schema().names()]
    if missing:
        raise ValueError(f"{what} lacks column(s) {', '.join(missing)}")
    return lazy


def _stack(series: pl.Series, trailing: tuple[int, ...]) -> np.ndarray:
    """An Array column as a float64 array (len, *trailing); reshape keeps the shape when the column is empty."""
    return np.array(series.to_numpy(), dtype=np.float64).reshape((len(series),) + trailing)  # a writable copy


def boxes_for_frames(
    frames: pl.DataFrame | pl.LazyFrame,
    annotations: pl.DataFrame | pl.LazyFrame,
    samples: pl.DataFrame | pl.LazyFrame,
) -> pl.DataFrame:
    """The global-frame boxes of each frame, as devkit `NuScenes.get_boxes(frame_token)` returns them.

    A keyframe, or a frame whose sample has no previous sample, gets its sample's annotations unchanged. Any
    other frame (a sweep) gets, for every annotation of its sample, the box interpolated between the same
    instance's annotation in the previous sample (at time t0) and this one (t1), at t = max(t0, min(t1,
    frame timestamp)): centre linearly (as `np.interp`), rotation by pyquaternion's slerp with amount
    (t - t0) / (t1 - t0). Annotations whose instance is not in the previous sample are used unchanged;
    instances only in the previous sample are dropped. The box keeps the current annotation's token, size
    and category, as the devkit's does.

    Args:
        frames: rows of `frames` (any modality): token, sample_token, timestamp, is_key_frame.
        annotations: rows of `annotations` covering the frames' samples and, for sweeps, their previous
            samples: token, sample_token, instance_token, category_name, translation, size, rotation.
        samples: rows of `tables/sample` covering the frames' samples and their previous samples: token,
            timestamp, prev.

    Returns:
        One row per (frame, box), ordered by frame then annotation (in the order of `annotations`):
        frame_index (u32, row of `frames`), frame_token, annotation_token, instance_token, category_name,
        translation (global, m), size ([w, l, h], m), rotation (global, [w, x, y, z]), interpolated (bool).

    Raises:
        ValueError: a frame's sample, or the previous sample of a sweep's sample, is not in `samples`.
    """
    frames_lazy = _lazy(frames, _FRAME_COLUMNS, "frames")
    annotations_lazy = _lazy(annotations, _ANNOTATION_COLUMNS, "annotations")
    samples_lazy = _lazy(samples, _SAMPLE_COLUMNS, "samples")

    frame_samples = (
        frames_lazy.with_row_index("frame_index")
        .select(
            "frame_index",
            pl.col("token").alias("frame_token"),
            "sample_token",
            pl.col("timestamp").alias("frame_timestamp"),
            "is_key_frame",
        )
        .join(
            samples_lazy.select(
                pl.col("token").alias("sample_token"),
                pl.col("timestamp").alias("sample_timestamp"),
                pl.col("prev").alias("prev_sample_token"),
            ),
            on="sample_token",
            how="left",
        )
        .join(
            samples_lazy.select(
                pl.col("token").alias("prev_sample_token"),
                pl.col("timestamp").alias("prev_sample_timestamp"),
            ),
            on="prev_sample_token",
            how="left",
        )
        # get_boxes interpolates exactly when the frame is not a keyframe and its sample has a prev.
        .with_columns(
            (~pl.col("is_key_frame") & (pl.col("prev_sample_token") != "")).alias("between_samples")
        )
        .collect()
    )
    _check_samples_known(frame_samples)
    # Each frame with its sample's boxes, and each box with the same instance's box one sample earlier.
    joined = (
        frame_samples.lazy()
        .join(
            annotations_lazy.with_row_index("annotation_index").select(
                "annotation_index",
                "sample_token",
                pl.col("token").alias("annotation_token"),
                "instance_token",
                pl.col("category_name").cast(pl.String),
                "translation",
                "size",
                "rotation",
            ),
            on="sample_token",
            how="inner",
        )
        .join(
            annotations_lazy.select(
                pl.col("sample_token").alias("prev_sample_token"),
                "instance_token",
                pl.col("translation").alias("prev_translation"),
                pl.col("rotation").alias("prev_rotation"),
            )
            # The devkit maps instance -> previous annotation with a dict, so a (malformed) duplicate instance
            # in one sample yields one box, the last one, rather than one box per duplicate.
            .unique(["prev_sample_token", "instance_token"], keep="last", maintain_order=True),
            on=["prev_sample_token", "instance_token"],
            how="left",
        )
        .with_columns(
            (pl.col("between_samples") & pl.col("prev_translation").is_not_null()).alias("interpolated"),
        )
        # Joins do not promise an order; callers line boxes up with frames, so fix one.
        .sort("frame_index", "annotation_index")
        .collect()
    )

    interpolate = joined["interpolated"].to_numpy()
    translation_m = _stack(joined["translation"], (3,))
    rotation_wxyz = _stack(joined["rotation"], (4,))
    if interpolate.any():
        rows = np.flatnonzero(interpolate)
        part = joined.select(
            "prev_sample_timestamp", "sample_timestamp", "frame_timestamp", "prev_translation", "prev_rotation"
        )[rows]
        t0 = part["prev_sample_timestamp"].to_numpy().astype(np.int64)
        t1 = part["sample_timestamp"].to_numpy().astype(np.int64)
        t = np.maximum(t0, np.minimum(t1, part["frame_timestamp"].to_numpy().astype(np.int64)))
        translation_m[rows] = _interp_two_points(
            t, t0, t1, _stack(part["prev_translation"], (3,)), translation_m[rows]
        )
        # The devkit divides Python ints; microsecond timestamps are exact in float64, so this rounds the same.
        with np.errstate(divide="ignore", invalid="ignore"):
            amount = np.where(t1 != t0, (t - t0).astype(np.float64) / (t1 - t0).astype(np.float64), 1.0)
        rotation_wxyz[rows] = geometry.quaternion_slerp(
            _stack(part["prev_rotation"], (4,)), rotation_wxyz[rows], amount
        )

    return joined.select(
        "frame_index", "frame_token", "annotation_token", "instance_token", "category_name",
    ).with_columns(
        pl.Series("translation", translation_m, dtype=pl.Array(pl.Float64, 3)),
        pl.Series("size", _stack(joined["size"], (3,)), dtype=pl.Array(pl.Float64, 3)),
        pl.Series("rotation", rotation_wxyz, dtype=pl.Array(pl.Float64, 4)),
        joined["interpolated"],
    )


def _check_samples_known(frame_samples: pl.DataFrame) -> None:
    """Raise if a frame's sample (or a sweep's previous sample) was not passed: its boxes would silently go."""
    unknown = (
        frame_samples.filter(
            pl.col("sample_timestamp").is_null()
            | (pl.col("between_samples") & pl.col("prev_sample_timestamp").is_null())
        )
        .select("frame_token", "sample_token", "prev_sample_token")
        .head(1)
    )
    if unknown.height:
        row = unknown.row(0, named=True)
        missing = row["sample_token"] if row["prev_sample_token"] is None else row["prev_sample_token"]
        raise ValueError(
            f"samples lacks sample {missing!r} needed for frame {row['frame_token']!r}; pass the sample table "
            "rows of the frames' samples and of their previous samples"
        )


def _interp_two_points(t: np.ndarray, t0: np.ndarray, t1: np.ndarray, c0: np.ndarray, c1: np.ndarray) -> np.ndarray:
    """`np.interp(t, [t0, t1], [c0, c1])` per row, with numpy's own formula and end cases, so the centres match
    the devkit's to the last bit: c1 at t == t1, c0 at t == t0, else c0 + slope * (t - t0).

    t, t0, t1: (N,) int64 microseconds with t0 <= t <= t1; c0, c1: (N, 3). Returns (N, 3).
    """
    t, t0, t1 = (np.asarray(a, dtype=np.float64)[:, None] for a in (t, t0, t1))
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (c1 - c0) / (t1 - t0)
        inside = slope * (t - t0) + c0
    return np.where(t == t1, c1, np.where(t == t0, c0, inside))


@dataclass(frozen=True)
class ProjectedBoxes:
    """Boxes projected into camera frames: M (frame, box) rows as aligned arrays.

    Attributes:
        frame_index: (M,) int64 row of the `frames` passed to `project_boxes`.
        frame_token: (M,) str camera sample_data token.
        annotation_token: (M,) str sample_annotation token (for an interpolated sweep box, the current
            sample's annotation, as the devkit's `Box.token`).
        instance_token: (M,) str.
        category_name: (M,) str.
        interpolated: (M,) bool, the box was interpolated between two samples.
        corners_camera_m: (M, 8, 3) corners in the camera frame (x right, y down, z forward), metres, in
            `Box.corners()` order (0-3 front face).
        corners_px: (M, 8, 2) corners in the image, pixels [u, v] (`view_points(..., normalize=True)`); a
            corner behind the camera projects mirrored, as in the devkit.
        depths: (M, 8) corner depth (camera z), metres.
        corner_visible: (M, 8) bool, 0 < u < width, 0 < v < height and depth > 1 m (devkit box_in_image).
        in_front: (M,) bool, every corner deeper than 0.1 m.
        visible: (M,) bool, some corner visible and the box in front: devkit BoxVisibility.ANY.
        center_ego_m: (M, 3) box centre in the frame's ego frame, metres.
        center_camera_m: (M, 3) box centre in the camera frame, metres.
        distance_m: (M,) distance from the camera to the box centre, metres (draw far to near).
    """

    frame_index: np.ndarray
    frame_token: np.ndarray
    annotation_token: np.ndarray
    instance_token: np.ndarray
    category_name: np.ndarray
    interpolated: np.ndarray
    corners_camera_m: np.ndarray
    corners_px: np.ndarray
    depths: np.ndarray
    corner_visible: np.ndarray
    in_front: np.ndarray
    visible: np.ndarray
    center_ego_m: np.ndarray
    center_camera_m: np.ndarray
    distance_m: np.ndarray

    def __len__(self) -> int:
        return len(self.frame_token)

    def take(self, rows) -> ProjectedBoxes:
        """The subset at `rows` (an index array or boolean mask over M)."""
        return ProjectedBoxes(**{f.name: getattr(self, f.name)[rows] for f in fields(self)})

    def to_polars(self) -> pl.DataFrame:
        """One row per box; (M, k) arrays become Array columns (corners_px: Array(Array(f64, 2), 8))."""
        return pl.DataFrame(
            [
                pl.Series("frame_index", self.frame_index, dtype=pl.Int64),
                pl.Series("frame_token", self.frame_token, dtype=pl.String),
                pl.Series("annotation_token", self.annotation_token, dtype=pl.String),
                pl.Series("instance_token", self.instance_token, dtype=pl.String),
                pl.Series("category_name", self.category_name, dtype=pl.String),
                pl.Series("interpolated", self.interpolated, dtype=pl.Boolean),
                pl.Series("corners_camera_m", self.corners_camera_m, dtype=pl.Array(pl.Float64, (8, 3))),
                pl.Series("corners_px", self.corners_px, dtype=pl.Array(pl.Float64, (8, 2))),
                pl.Series("depths", self.depths, dtype=pl.Array(pl.Float64, 8)),
                pl.Series("corner_visible", self.corner_visible, dtype=pl.Array(pl.Boolean, 8)),
                pl.Series("in_front", self.in_front, dtype=pl.Boolean),
                pl.Series("visible", self.visible, dtype=pl.Boolean),
                pl.Series("center_ego_m", self.center_ego_m, dtype=pl.Array(pl.Float64, 3)),
                pl.Series("center_camera_m", self.center_camera_m, dtype=pl.Array(pl.Float64, 3)),
                pl.Series("distance_m", self.distance_m, dtype=pl.Float64),
            ]
        )


def camera_transforms(frames: pl.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame transforms of camera frames, from their poses (not from the precomputed matrix columns).

    Args:
        frames: F camera rows of `frames` (ego_translation, ego_rotation, sensor_translation, sensor_rotation,
            camera_intrinsic).

    Returns:
        ego_from_global (F, 4, 4) at each frame's own timestamp, camera_from_ego (F, 4, 4), and the
        intrinsics (F, 3, 3).
    """
    global_from_ego = geometry.rigid_transforms(
        _stack(frames["ego_translation"], (3,)), _stack(frames["ego_rotation"], (4,))
    )
    ego_from_camera = geometry.rigid_transforms(
        _stack(frames["sensor_translation"], (3,)), _stack(frames["sensor_rotation"], (4,))
    )
    intrinsic = _stack(frames["camera_intrinsic"], (3, 3))
    return geometry.invert_rigid(global_from_ego), geometry.invert_rigid(ego_from_camera), intrinsic


def project_boxes(
    frames: pl.DataFrame | pl.LazyFrame,
    annotations: pl.DataFrame | pl.LazyFrame,
    samples: pl.DataFrame | pl.LazyFrame,
    visibility: Visibility = "any",
) -> ProjectedBoxes:
    """The boxes of camera frames in their images, as devkit `get_sample_data(frame, box_vis_level)` + `view_points`.

    For every camera frame, the boxes of `boxes_for_frames` (interpolated for sweeps) move global -> ego with
    the ego pose of *that* frame -> camera (inverse of ego_from_sensor) -> image (`view_points`, normalised),
    and are filtered like devkit `box_in_image`: a corner is visible when 0 < u < width, 0 < v < height and
    depth > 1 m; "any" keeps boxes with some visible corner and every corner deeper than 0.1 m, "all" boxes
    with every corner visible (and deeper than 0.1 m), "none" keeps every box.

    Args:
        frames: rows of `frames`: token, sample_token, timestamp, is_key_frame, width, height,
            ego_translation, ego_rotation, sensor_translation, sensor_rotation, camera_intrinsic. Rows
            without an intrinsic (lidar, radar) get no boxes.
        annotations, samples: as for `boxes_for_frames`.
        visibility: "any", "all" or "none" (devkit BoxVisibility.ANY / ALL / NONE).

    Returns:
        The kept boxes, ordered by frame then annotation.
    """
    if visibility not in VISIBILITIES:
        raise ValueError(f"visibility must be one of {', '.join(VISIBILITIES)}, got {visibility!r}")
    camera_frames = (
        _lazy(frames, _FRAME_COLUMNS + _CAMERA_COLUMNS, "frames")
        .with_row_index("frame_index")
        .filter(pl.col("camera_intrinsic").is_not_null())
        .collect()
    )
    boxes = boxes_for_frames(camera_frames.drop("frame_index"), annotations, samples)
    # boxes.frame_index counts rows of camera_frames; map it back to rows of the caller's `frames`.
    camera_row = boxes["frame_index"].to_numpy().astype(np.int64)
    frame_index = camera_frames["frame_index"].to_numpy().astype(np.int64)[camera_row]

    ego_from_global, camera_from_ego, intrinsic = camera_transforms(camera_frames)
    ego_from_global, camera_from_ego, intrinsic = (
        ego_from_global[camera_row], camera_from_ego[camera_row], intrinsic[camera_row]
    )
    width_px = camera_frames["width"].to_numpy().astype(np.float64)[camera_row]
    height_px = camera_frames["height"].to_numpy().astype(np.float64)[camera_row]

    # Move centre and orientation (as the devkit moves a Box), then build corners in the camera frame: corners
    # built in the global frame would carry ~1e3 m coordinates through the subtraction.
    center_global_m = _stack(boxes["translation"], (3,))
    center_ego_m = geometry.transform_points(ego_from_global, center_global_m)
    center_camera_m = geometry.transform_points(camera_from_ego, center_ego_m)
    global_from_box_rotation = geometry.rotation_matrices(_stack(boxes["rotation"], (4,)))
    camera_from_box_rotation = camera_from_ego[:, :3, :3] @ ego_from_global[:, :3, :3] @ global_from_box_rotation
    corners_camera_m = geometry.box_corners(center_camera_m, _stack(boxes["size"], (3,)), camera_from_box_rotation)

    corners_px = geometry.view_points(corners_camera_m, intrinsic, normalize=True)[..., :2]
    depths = corners_camera_m[..., 2]
    u, v = corners_px[..., 0], corners_px[..., 1]
    corner_visible = (
        (u > 0) & (u < width_px[:, None]) & (v < height_px[:, None]) & (v > 0) & (depths > CORNER_MIN_DEPTH_M)
    )
    in_front = np.all(depths > BOX_MIN_DEPTH_M, axis=1)
    visible = np.any(corner_visible, axis=1) & in_front

    projected = ProjectedBoxes(
        frame_index=frame_index,
        frame_token=boxes["frame_token"].to_numpy(),
        annotation_token=boxes["annotation_token"].to_numpy(),
        instance_token=boxes["instance_token"].to_numpy(),
        category_name=boxes["category_name"].to_numpy(),
        interpolated=boxes["interpolated"].to_numpy(),
        corners_camera_m=corners_camera_m,
        corners_px=corners_px,
        depths=depths,
        corner_visible=corner_visible,
        in_front=in_front,
        visible=visible,
        center_ego_m=center_ego_m,
        center_camera_m=center_camera_m,
        distance_m=np.linalg.norm(center_camera_m, axis=1),
    )
    if visibility == "any":
        return projected.take(visible)
    if visibility == "all":
        return projected.take(np.all(corner_visible, axis=1) & in_front)
    return projected


def project_lidar_to_image(
    points_sensor_m: np.ndarray,
    lidar_frame: Mapping,
    camera_frame: Mapping,
    width_px: int | None = None,
    height_px: int | None = None,
    min_depth_m: float = POINT_MIN_DEPTH_M,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lidar points in a camera image, as devkit `NuScenesExplorer.map_pointcloud_to_image`.

    Points go lidar -> ego at the lidar's timestamp -> global -> ego at the camera's timestamp -> camera ->
    image, and are kept when depth > min_depth_m and 1 < u < width - 1, 1 < v < height - 1 (the devkit's
    1-pixel margin). Computed in float64 (the devkit rounds to float32 after each step, which moves points by
    up to ~1e-4 m in the global frame).

    Args:
        points_sensor_m: (P, 3+) points in the lidar frame, metres; extra columns (intensity, ring) ignored.
        lidar_frame: a `frames` row of the point sensor (mapping with ego_translation, ego_rotation,
            sensor_translation, sensor_rotation), e.g. `frames.row(i, named=True)`.
        camera_frame: a `frames` row of the camera (the same, plus camera_intrinsic, width, height).
        width_px, height_px: image size; default the camera row's width and height (the devkit reads them
            from the image file).
        min_depth_m: points closer to the camera plane are dropped.

    Returns:
        uv (K, 2) pixels, depth (K,) metres (camera z), index (K,) int64 rows of `points_sensor_m` kept.
    """
    points_sensor_m = np.asarray(points_sensor_m)[:, :3].astype(np.float64)
    global_from_lidar_ego = geometry.rigid_transforms(lidar_frame["ego_translation"], lidar_frame["ego_rotation"])
    lidar_ego_from_lidar = geometry.rigid_transforms(lidar_frame["sensor_translation"], lidar_frame["sensor_rotation"])
    global_from_camera_ego = geometry.rigid_transforms(camera_frame["ego_translation"], camera_frame["ego_rotation"])
    camera_ego_from_camera = geometry.rigid_transforms(
        camera_frame["sensor_translation"], camera_frame["sensor_rotation"]
    )

    # Step by step rather than one composed matrix, the order the devkit applies them.
    points_global_m = geometry.transform_points(
        global_from_lidar_ego, geometry.transform_points(lidar_ego_from_lidar, points_sensor_m)
    )
    points_camera_m = geometry.transform_points(
        geometry.invert_rigid(camera_ego_from_camera),
        geometry.transform_points(geometry.invert_rigid(global_from_camera_ego), points_global_m),
    )

    width_px = camera_frame["width"] if width_px is None else width_px
    height_px = camera_frame["height"] if height_px is None else height_px
    depth_m = points_camera_m[:, 2]
    uv = geometry.view_points(points_camera_m, np.asarray(camera_frame["camera_intrinsic"], dtype=np.float64))[:, :2]
    keep = (
        (depth_m > min_depth_m)
        & (uv[:, 0] > POINT_MARGIN_PX)
        & (uv[:, 0] < width_px - POINT_MARGIN_PX)
        & (uv[:, 1] > POINT_MARGIN_PX)
        & (uv[:, 1] < height_px - POINT_MARGIN_PX)
    )
    index = np.flatnonzero(keep)
    return uv[index], depth_m[index], index
