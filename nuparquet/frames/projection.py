"""Boxes in camera images, for many camera frames at once, exactly as devkit `get_sample_data` does it.

The input is rows of the converted datasets (`schemas/frames.json`, `schemas/annotations.json`, and the
`tables/sample` table), as polars DataFrames or LazyFrames:

    frames = ds.scan("frames").filter(pl.col("scene_name") == "scene-0061", pl.col("modality") == "camera")
    samples = ds.scan("tables/sample")
    annotations = ds.scan("annotations").filter(pl.col("scene_name") == "scene-0061")
    projected = project_boxes(frames, annotations, samples, visibility="any")

`nuparquet.frames.boxes` pairs every frame with its boxes (interpolated for sweeps), the cameras are built once
from the stored transforms (`frames.poses`), and the geometry runs once over all (frame, box) pairs. The
devkit functions reproduced: `NuScenes.get_sample_data`, `geometry_utils.view_points` and `box_in_image`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import polars as pl

from nuparquet.frames.boxes import FRAME_COLUMNS, FramedCuboids, box_series, frame_boxes, lazy_with
from nuparquet.frames.poses import CAMERA_COLUMNS, cameras_from_frames, pose_columns
from nuparquet.geometry import Cameras, box_half_axes, corners_from_half_axes
from nuparquet.geometry.box_projection import project_pairs
from nuparquet.geometry.cuboids import CuboidRows

Visibility = Literal["any", "all", "none"]
VISIBILITIES: tuple[str, ...] = ("any", "all", "none")


@dataclass(frozen=True)
class BoxesInCameras:
    """M boxes seen by their cameras: centres and corners in the camera frame.

    center_ego_m: (M, 3) centre in the frame's ego frame; center_camera_m: (M, 3) in the camera frame;
    corners_camera_m: (M, 8, 3) corners in the camera frame in `Box.corners()` order (0-3 front face).
    """

    center_ego_m: np.ndarray
    center_camera_m: np.ndarray
    corners_camera_m: np.ndarray


def boxes_in_cameras(cameras: Cameras, boxes: FramedCuboids) -> BoxesInCameras:
    """Move each box into its frame's camera (`boxes.frame_index` names it among the F `cameras`), as the devkit
    moves a `Box`: centre global -> ego -> camera, then the corners built in the camera frame (corners built in
    the global frame would carry ~1e3 m coordinates through the subtraction).

    Each frame's rotation global -> camera is composed once and each annotation's half-axes are built once (not
    once per camera that sees it): no (M, 4, 4) copy of the cameras, one batched product for the corners.
    """
    frame = boxes.frame_index
    ego_rotation, ego_translation = cameras.ego_from_global[:, :3, :3], cameras.ego_from_global[:, :3, 3]
    cam_rotation, cam_translation = cameras.camera_from_ego[:, :3, :3], cameras.camera_from_ego[:, :3, 3]
    # Row vectors times transposed rotations, the transposes made contiguous once per frame: numpy's stacked
    # matmul is several times faster on contiguous (M, 3, 3) operands than on transposed views.
    center_ego_m = (boxes.translation_m[:, None, :] @ _transposed(ego_rotation)[frame])[:, 0] + ego_translation[frame]
    center_camera_m = (center_ego_m[:, None, :] @ _transposed(cam_rotation)[frame])[:, 0] + cam_translation[frame]
    global_to_camera_t = _transposed(cam_rotation @ ego_rotation)
    corners_camera_m = corners_from_half_axes(_half_axes_global(boxes) @ global_to_camera_t[frame])
    corners_camera_m += center_camera_m[:, None, :]
    return BoxesInCameras(center_ego_m, center_camera_m, corners_camera_m)


def _transposed(matrices: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.swapaxes(matrices, -1, -2))


def _half_axes_global(boxes: FramedCuboids) -> np.ndarray:
    """(M, 3, 3) each box's half-axes in the global frame (`geometry.box_half_axes`), built once per annotation
    (a keyframe annotation is seen by up to six cameras) and once per interpolated sweep box."""
    table, row = half_axes_table(boxes)
    return table[row]


def half_axes_table(boxes: FramedCuboids) -> tuple[np.ndarray, np.ndarray]:
    """The distinct half-axes of M boxes, (K, 3, 3) global frame, and each box's row of them (M,): one row per
    source box (an annotation is seen by up to six cameras) and one per interpolated sweep box."""
    moved = np.flatnonzero(boxes.interpolated)
    fixed = np.flatnonzero(~boxes.interpolated) if len(moved) else slice(None)
    _, first, inverse = np.unique(boxes.source_index[fixed], return_index=True, return_inverse=True)
    once = np.arange(len(boxes))[fixed][first]
    per_annotation = box_half_axes(boxes.size_wlh_m[once], boxes.rotation_wxyz[once])
    if not len(moved):  # keyframes only: every box is its annotation's
        return per_annotation, inverse.reshape(-1)
    row = np.empty(len(boxes), dtype=np.int64)
    row[fixed] = inverse.reshape(-1)
    row[moved] = len(per_annotation) + np.arange(len(moved))
    table = np.concatenate([per_annotation, box_half_axes(boxes.size_wlh_m[moved], boxes.rotation_wxyz[moved])])
    return table, row


@dataclass(frozen=True)
class ProjectedBoxes(CuboidRows):
    """Boxes projected into camera frames: M (frame, box) rows as aligned arrays.

    Attributes:
        cuboids: (M,) the boxes projected, in the global frame (`frame_boxes`' values).
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

    def to_polars(self) -> pl.DataFrame:
        """One row per box; (M, k) arrays become Array columns (corners_px: Array(Array(f64, 2), 8)); the cuboids
        as `boxes_for_frames` names them (translation, size, rotation: global)."""
        return pl.DataFrame(
            [
                *box_series(self, pl.Int64),
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


def camera_rows(frames: pl.DataFrame | pl.LazyFrame) -> pl.DataFrame:
    """The camera rows of `frames` (those with an intrinsic) with their row number in `frames` as
    `frame_index`, and the columns projection needs."""
    lazy = frames.lazy()
    names = lazy.collect_schema().names()
    needed = FRAME_COLUMNS + CAMERA_COLUMNS + pose_columns(names)
    return (
        lazy_with(lazy, needed, "frames")
        .with_row_index("frame_index")
        .filter(pl.col("camera_intrinsic").is_not_null())
        .select("frame_index", *needed)
        .collect()
    )


def project_boxes(
    frames: pl.DataFrame | pl.LazyFrame,
    annotations: pl.DataFrame | pl.LazyFrame,
    samples: pl.DataFrame | pl.LazyFrame,
    visibility: Visibility = "any",
) -> ProjectedBoxes:
    """The boxes of camera frames in their images, as devkit `get_sample_data(frame, box_vis_level)` + `view_points`.

    For every camera frame, the boxes of `frame_boxes` (interpolated for sweeps) move global -> ego with
    the ego pose of *that* frame -> camera (inverse of ego_from_sensor) -> image (`view_points`, normalised),
    and are filtered like devkit `box_in_image`: a corner is visible when 0 < u < width, 0 < v < height and
    depth > 1 m; "any" keeps boxes with some visible corner and every corner deeper than 0.1 m, "all" boxes
    with every corner visible (and deeper than 0.1 m), "none" keeps every box.

    Args:
        frames: rows of `frames`: token, sample_token, timestamp, is_key_frame, width, height,
            camera_intrinsic, and global_from_ego + ego_from_sensor (or the poses ego_translation,
            ego_rotation, sensor_translation, sensor_rotation). Rows without an intrinsic (lidar, radar) get
            no boxes.
        annotations, samples: as for `nuparquet.frames.boxes.frame_boxes`.
        visibility: "any", "all" or "none" (devkit BoxVisibility.ANY / ALL / NONE).

    Returns:
        The kept boxes, ordered by frame then annotation.
    """
    if visibility not in VISIBILITIES:
        raise ValueError(f"visibility must be one of {', '.join(VISIBILITIES)}, got {visibility!r}")
    cameras_df = camera_rows(frames)
    boxes = frame_boxes(cameras_df.drop("frame_index"), annotations, samples)
    cameras = cameras_from_frames(cameras_df)  # F cameras; boxes.frame_index counts camera rows
    half_axes, axes_row = half_axes_table(boxes)
    seen = project_pairs(cameras, boxes.frame_index, boxes.translation_m, half_axes, axes_row)

    projected = ProjectedBoxes(
        cuboids=boxes.cuboids,
        frame_index=cameras_df["frame_index"].to_numpy().astype(np.int64)[boxes.frame_index],
        frame_token=boxes.frame_token,
        annotation_token=boxes.annotation_token,
        instance_token=boxes.instance_token,
        category_name=boxes.category_name,
        interpolated=boxes.interpolated,
        corners_camera_m=seen.corners_camera_m,
        corners_px=seen.corners_px,
        depths=seen.depths,
        corner_visible=seen.corner_visible,
        in_front=seen.in_front,
        visible=seen.visible,
        center_ego_m=seen.center_ego_m,
        center_camera_m=seen.center_camera_m,
        distance_m=seen.distance_m,
    )
    if visibility == "any":
        return projected.take(seen.visible)
    if visibility == "all":
        return projected.take(np.all(seen.corner_visible, axis=1) & seen.in_front)
    return projected
