"""One pinhole camera model for many camera frames at once (numpy only): the batch form of av2-api's
`geometry/camera/pinhole_camera.py`.

A `Cameras` value holds, for F camera frames, where each camera was (`ego_from_global` at the frame's own
timestamp, `camera_from_ego` from its calibration), its intrinsics `image_from_camera` and the size of the
image its pixels address. It is built once per query (`nuparquet.frames.poses.cameras_from_frames`
reads the stored transform columns of `frames`) and asked to move points into the cameras, to project them,
to clip segments at the near plane, and to describe a resized image:

```python
cameras = cameras_from_frames(frames)                   # (F,) cameras at full size
tiles = cameras.resized_to((800, 450))                  # the same cameras drawing into 800x450 tiles
uv, depth = tiles.take(rows).project(tiles.take(rows).to_camera(points_global))
```

Conventions (the devkit's and OpenCV's): pixel centres sit at integer coordinates, so resizing an image by s
maps u to s * (u + 0.5) - 0.5 (`projection.scale_pixels`, what `cv2.resize` does). A camera remembers how far it was
resized (`scale`), so "inside the image" keeps the devkit's meaning on the full-size image (0 < u < width,
`in_image`) whatever the size of the pixels it projects to. Camera axes: x right, y down, z forward.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from nuparquet.geometry.projection import NEAR_PLANE_M, perspective, pixels_in_image, scale_intrinsic
from nuparquet.geometry.rigid import invert_rigid, transform_points


@dataclass(frozen=True)
class Cameras:
    """F pinhole cameras, one per camera frame.

    Attributes:
        ego_from_global: (F, 4, 4) the ego pose at each frame's own timestamp, inverted.
        camera_from_ego: (F, 4, 4) each camera's calibration, inverted.
        image_from_camera: (F, 3, 3) intrinsics of the image the pixels address (resized ones included).
        size_px: (F, 2) float64 [width, height] of that image, in its pixels (width * sx when resized).
        scale: (F, 2) float64 [sx, sy] of that image relative to the calibrated one (1 unless resized).

    The extrinsics are kept as two steps rather than one `camera_from_global`, and points move through them
    in the devkit's order (global -> ego -> camera): projections agree with the devkit to ~1e-12 px.
    """

    ego_from_global: np.ndarray
    camera_from_ego: np.ndarray
    image_from_camera: np.ndarray
    size_px: np.ndarray
    scale: np.ndarray

    @classmethod
    def from_poses(cls, global_from_ego, ego_from_camera, image_from_camera, size_px) -> Cameras:
        """Cameras from the stored poses: global_from_ego (F, 4, 4), ego_from_camera (F, 4, 4), intrinsics
        (F, 3, 3) and (F, 2) [width, height] of the calibrated images."""
        size_px = np.asarray(size_px, dtype=np.float64).reshape(-1, 2)
        return cls(
            ego_from_global=invert_rigid(global_from_ego),
            camera_from_ego=invert_rigid(ego_from_camera),
            image_from_camera=np.asarray(image_from_camera, dtype=np.float64).reshape(-1, 3, 3),
            size_px=size_px,
            scale=np.ones_like(size_px),
        )

    def __len__(self) -> int:
        return len(self.size_px)

    @property
    def camera_from_global(self) -> np.ndarray:
        """(F, 4, 4) the composed extrinsics."""
        return self.camera_from_ego @ self.ego_from_global

    def take(self, rows) -> Cameras:
        """The cameras at `rows` (an index array, possibly repeating, or a boolean mask over F)."""
        return Cameras(**{f.name: getattr(self, f.name)[rows] for f in fields(self)})

    def resized(self, scale) -> Cameras:
        """The same cameras drawing into images resized by `scale`: one factor, (2,) [sx, sy], or (F, 2)."""
        scale = np.broadcast_to(np.asarray(scale, dtype=np.float64), self.size_px.shape)
        return Cameras(
            ego_from_global=self.ego_from_global,
            camera_from_ego=self.camera_from_ego,
            image_from_camera=scale_intrinsic(self.image_from_camera, scale),
            size_px=self.size_px * scale,
            scale=self.scale * scale,
        )

    def resized_to(self, size_px) -> Cameras:
        """The same cameras drawing into images of exactly `size_px` [width, height] ((2,) or (F, 2))."""
        size_px = np.broadcast_to(np.asarray(size_px, dtype=np.float64), self.size_px.shape)
        resized = self.resized(size_px / self.size_px)
        return Cameras(resized.ego_from_global, resized.camera_from_ego, resized.image_from_camera,
                       size_px.copy(), resized.scale)

    def to_camera(self, points_global_m) -> np.ndarray:
        """Global points -> camera frame, metres: (F, 3) one point per camera or (F, K, 3) K per camera."""
        return transform_points(self.camera_from_ego, transform_points(self.ego_from_global,
                                                                                          points_global_m))

    def to_ego(self, points_global_m) -> np.ndarray:
        """Global points -> each frame's ego frame, metres ((F, 3) or (F, K, 3))."""
        return transform_points(self.ego_from_global, points_global_m)

    def rotation_to_camera(self, global_from_object_rotation) -> np.ndarray:
        """(F, 3, 3) orientations in the global frame -> in the camera frame."""
        return self.camera_from_ego[:, :3, :3] @ self.ego_from_global[:, :3, :3] @ global_from_object_rotation

    def project(self, points_camera_m) -> tuple[np.ndarray, np.ndarray]:
        """Perspective projection (devkit `view_points(..., normalize=True)`).

        Args:
            points_camera_m: (F, 3) or (F, K, 3) points in the camera frame, metres.

        Returns:
            uv: pixels [u, v] of the shape of the points with 2 coordinates; a point behind the camera projects
            mirrored, one at depth 0 to inf/nan, as in the devkit. depth: camera z, metres.
        """
        return perspective(self.image_from_camera, points_camera_m)

    def in_image(self, uv, margin_px: float = 0.0) -> np.ndarray:
        """Whether pixels lie inside the image, as the devkit tests it on the full-size image:
        margin < u < width - margin and margin < v < height - margin (box_in_image: margin 0;
        map_pointcloud_to_image: 1). `margin_px` is in full-size pixels; for a resized camera the same region
        is tested in its own pixels.

        Args:
            uv: (F, 2) or (F, K, 2) pixels of these cameras.

        Returns:
            bool array of the shape of `uv` without its last axis.
        """
        return pixels_in_image(uv, self.size_px, self.scale, margin_px)

    def clip_segments(self, segments_camera_m, near_m: float = NEAR_PLANE_M) -> tuple[np.ndarray, np.ndarray]:
        """Clip segments to the half-space z >= near_m in the camera frame, then project them.

        Args:
            segments_camera_m: (F, S, 2, 3) S segments per camera, [start, end] points in the camera frame.
            near_m: the near plane.

        Returns:
            segments_px: (F, S, 2, 2) projected end points of the clipped segments (NaN where dropped).
            keep: (F, S) bool, False for segments entirely behind the near plane.
        """
        segments_camera_m = np.asarray(segments_camera_m, dtype=np.float64)
        start, end = segments_camera_m[..., 0, :], segments_camera_m[..., 1, :]
        z_start, z_end = start[..., 2], end[..., 2]
        keep = (z_start >= near_m) | (z_end >= near_m)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (near_m - z_start) / (z_end - z_start)  # where the line crosses the near plane
            crossing = start + t[..., None] * (end - start)
        crossing[..., 2] = near_m  # exactly on the plane, whatever the rounding
        start = np.where((z_start < near_m)[..., None], crossing, start)
        end = np.where((z_end < near_m)[..., None], crossing, end)
        clipped = np.stack([start, end], axis=-2)  # (F, S, 2, 3)
        with np.errstate(divide="ignore", invalid="ignore"):
            projected = np.einsum("fij,fsej->fsei", self.image_from_camera, clipped)
            segments_px = projected[..., :2] / projected[..., 2:3]
        segments_px[~keep] = np.nan
        return segments_px, keep

    def unproject(self, uv, depth_m) -> np.ndarray:
        """Undo `project`: pixels (F, K, 2) and depths (F, K) back to camera-frame points (F, K, 3), metres
        (p = z K^-1 [u, v, 1]; exact up to rounding for z != 0, points behind the camera come back behind it)."""
        uv = np.asarray(uv, dtype=np.float64)
        homogeneous = np.concatenate([uv, np.ones(uv.shape[:-1] + (1,))], axis=-1)
        rays = homogeneous @ np.swapaxes(np.linalg.inv(self.image_from_camera), -1, -2)
        return rays * np.asarray(depth_m, dtype=np.float64)[..., None]
