"""Geometry of nuScenes data, vectorised over boxes and frames: numpy only (no polars, no files, no drawing),
so it can be tested against the devkit in isolation.

Conventions follow nuscenes-devkit and pyquaternion exactly, so results can be checked against them:

- Quaternions are arrays `[..., 4]` in `[w, x, y, z]` order (the nuScenes JSON order).
- A transform `X_from_Y` is a `(4, 4)` (or stacked `(N, 4, 4)`) row-major matrix mapping points in frame Y to
  frame X, built from the pose of Y expressed in X; chains read like algebra:
  `global_from_sensor = global_from_ego @ ego_from_sensor`.
- Lengths are metres, box sizes `[width, length, height]` (the devkit's `wlh`), angles radians.

Modules: `quaternions` (pyquaternion's semantics over arrays), `rigid` (transforms), `boxes` (cuboid corners,
points in boxes), `projection` (view_points, perspective projection, pixel scaling, the box_in_image rule),
`camera` (`Cameras`: many pinhole cameras at once), `cuboids` (`Cuboids`: the one box type), `interpolation` (between two samples, as `get_boxes`).
The names below are the package's public face.
"""

from nuparquet.geometry.boxes import box_corners, box_half_axes, corners_from_half_axes, count_points_in_boxes
from nuparquet.geometry.camera import Cameras
from nuparquet.geometry.cuboids import Cuboids, CuboidRows
from nuparquet.geometry.interpolation import interp_two_points, slerp_amount
from nuparquet.geometry.projection import (
    CORNER_MIN_DEPTH_M, NEAR_PLANE_M, box_visibility, perspective, pixels_in_image, scale_intrinsic, scale_pixels,
    view_points,
)
from nuparquet.geometry.quaternions import (
    heading_from_quaternions, invert_quaternions, multiply_quaternions, normalise_quaternions, quaternion_slerp,
    rotation_matrices, vehicle_flat_from_vehicle, yaw_from_quaternions,
)
from nuparquet.geometry.rigid import invert_rigid, rigid_transforms, transform_points

__all__ = [
    "CORNER_MIN_DEPTH_M", "Cameras", "CuboidRows", "Cuboids", "NEAR_PLANE_M", "box_corners", "box_half_axes", "box_visibility",
    "corners_from_half_axes", "count_points_in_boxes", "heading_from_quaternions", "interp_two_points",
    "invert_quaternions", "invert_rigid", "multiply_quaternions", "normalise_quaternions", "perspective", "pixels_in_image", "quaternion_slerp", "rigid_transforms",
    "rotation_matrices", "scale_intrinsic", "scale_pixels", "slerp_amount", "transform_points",
    "vehicle_flat_from_vehicle", "view_points", "yaw_from_quaternions",
]
