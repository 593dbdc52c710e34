"""Sensor files of the synthetic dataset: camera JPEGs with painted cuboids, lidar `.pcd.bin` and radar `.pcd`.

What each frame shows is exactly what the devkit's `NuScenes.get_boxes(sample_data_token)` returns for it
(keyframes: the sample's annotations; sweeps: each annotation of the following sample, interpolated from its
track's annotation in the previous sample when there is one, linearly in the centre and by slerp in the
rotation), seen through the frame's own ego pose and calibration. A correct overlay therefore lines up with
the painted cuboids on every frame, keyframe or sweep.

- Cameras (JPEG, 1600x900 on the nuScenes rig): a sky-to-ground gradient, then every box whose eight corners are all at least
  0.1 m in front of the camera, far to near, as the filled convex hull of its projected corners in its
  category's colour (nuparquet.rendering.palette), outlined in a darker shade.
- Lidar (float32 rows x, y, z, intensity, ring in the lidar's own frame): `num_lidar_pts` points on the
  sensor-facing faces of each box (just inside them) and ring-pattern returns from the ground plane z = 0
  outside the boxes' footprints.
- Radar (PCD v0.7, the 18 fields of nuScenes radar): a few returns near each box with `num_radar_pts` > 0
  whose centre lies in the radar's +-60 degree field of view, plus clutter. A box's returns carry its velocity
  (the track's displacement from its previous sample over the time between, turned into the radar's frame) as
  `vx_comp`, `vy_comp` (and `vx`, `vy`: the ego's motion is not modelled); clutter is still.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from nuparquet.rendering.palette import category_rgb
from nuparquet.synth.plan import Rig
from nuparquet.synth.rigid import (
    box_corners, invert_rigid, quat_slerp, quat_to_matrix, rigid_matrix, transform_points,
)
from nuparquet.synth.taxonomy import CATEGORIES, LIDAR_RING_ELEVATIONS_DEG
from nuparquet.synth.world import SceneWorld

MIN_DEPTH_M = 0.1  # the devkit's box_in_image / view_points depth cut-off
JPEG_QUALITY = 90
GROUND_AZIMUTHS_PER_RING = 110
LIDAR_MAX_RANGE_M = 80.0
RADAR_HALF_FOV_RAD = np.deg2rad(60.0)
RADAR_MAX_RANGE_M = 100.0

CATEGORY_BGR = np.array([category_rgb(c.name)[::-1] for c in CATEGORIES], dtype=np.int64)  # (n_categories, 3)

_RADAR_DTYPE = np.dtype([  # packed (no padding), little-endian: 43 bytes per point, as in nuScenes
    ("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("dyn_prop", "i1"), ("id", "<i2"), ("rcs", "<f4"),
    ("vx", "<f4"), ("vy", "<f4"), ("vx_comp", "<f4"), ("vy_comp", "<f4"), ("is_quality_valid", "i1"),
    ("ambig_state", "i1"), ("x_rms", "i1"), ("y_rms", "i1"), ("invalid_state", "i1"), ("pdh0", "i1"),
    ("vx_rms", "i1"), ("vy_rms", "i1"),
])
_RADAR_HEADER = (
    "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
    "FIELDS x y z dyn_prop id rcs vx vy vx_comp vy_comp is_quality_valid ambig_state x_rms y_rms invalid_state "
    "pdh0 vx_rms vy_rms\nSIZE 4 4 4 1 2 4 4 4 4 4 1 1 1 1 1 1 1 1\nTYPE F F F I I F F F F F I I I I I I I I\n"
    "COUNT 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n"
    "DATA binary\n"
)

# Box faces in the box frame: (axis, sign) of the outward normal; the bottom face (z, -1) lies on the ground.
_FACE_AXIS = np.array([0, 0, 1, 1, 2])
_FACE_SIGN = np.array([1.0, -1.0, 1.0, -1.0, 1.0])


@dataclass(frozen=True)
class GeneratedBoxes:
    """The boxes one frame shows, in the global frame: the generator's own restatement (it shares no geometry with
    the package it checks: `nuparquet.geometry.cuboids` is what the converted data is read into)."""

    center_m: np.ndarray  # (B, 3)
    wlh_m: np.ndarray  # (B, 3)
    rotation: np.ndarray  # (B, 4) global_from_box
    category: np.ndarray  # (B,) index into CATEGORIES
    num_lidar_pts: np.ndarray  # (B,)
    num_radar_pts: np.ndarray  # (B,)


class SceneSensors:
    """Writes the sensor files of one scene."""

    def __init__(self, world: SceneWorld, rig: Rig, seed: int, scene_index: int):
        self.world = world
        self.rig = rig
        self.seed = seed
        self.scene_index = scene_index
        order = np.argsort(world.annotation_sample, kind="stable")
        bounds = np.searchsorted(world.annotation_sample[order], np.arange(world.timeline.sample_timestamp_us.size + 1))
        self._annotations_of_sample = [order[bounds[k]:bounds[k + 1]] for k in range(bounds.size - 1)]
        self._backgrounds: dict[int, np.ndarray] = {}  # per channel

    def frame_boxes(self, frame: int) -> GeneratedBoxes:
        """The devkit's `get_boxes` for one frame, vectorised over the boxes."""
        w, tl = self.world, self.world.timeline
        k = int(tl.frame_sample_index[frame])
        ann = self._annotations_of_sample[k]
        center = w.annotation_translation_m[ann]
        rotation = w.annotation_rotation[ann]
        if not tl.frame_is_key_frame[frame] and k > 0:
            t0, t1 = tl.sample_timestamp_us[k - 1], tl.sample_timestamp_us[k]
            t = min(max(int(tl.frame_timestamp_us[frame]), t0), t1)
            amount = (t - t0) / (t1 - t0)
            # Interpolated only when the track's previous annotation is in sample k - 1 (not across a gap).
            has_prev = w.annotation_has_prev[ann] & (w.annotation_sample[ann - 1] == k - 1)
            prev = ann[has_prev] - 1
            center = center.copy()
            rotation = rotation.copy()
            center[has_prev] = w.annotation_translation_m[prev] + amount * (center[has_prev]
                                                                            - w.annotation_translation_m[prev])
            rotation[has_prev] = quat_slerp(w.annotation_rotation[prev], rotation[has_prev],
                                            np.full(prev.size, amount))
        return GeneratedBoxes(center, w.annotation_size_m[ann], rotation, w.instance_category[w.annotation_instance[ann]],
                          w.annotation_num_lidar_pts[ann], w.annotation_num_radar_pts[ann])

    def box_velocity_mps(self, frame: int) -> np.ndarray:
        """(B, 3) global velocity of the boxes of `frame` (`frame_boxes` order): each track's displacement from its
        annotation in the previous sample over the time between; 0 at a track's start."""
        w, tl = self.world, self.world.timeline
        k = int(tl.frame_sample_index[frame])
        ann = self._annotations_of_sample[k]
        velocity = np.zeros((ann.size, 3))
        if k == 0 or not ann.size:
            return velocity
        has_prev = w.annotation_has_prev[ann] & (w.annotation_sample[ann - 1] == k - 1)
        dt_s = (tl.sample_timestamp_us[k] - tl.sample_timestamp_us[k - 1]) * 1e-6
        velocity[has_prev] = (w.annotation_translation_m[ann[has_prev]]
                              - w.annotation_translation_m[ann[has_prev] - 1]) / dt_s
        return velocity

    def sensor_from_global(self, frame: int) -> np.ndarray:
        """(4, 4) transform from the global frame into the frame's sensor frame (through its own ego pose)."""
        channel = int(self.world.timeline.frame_channel[frame])
        global_from_ego = rigid_matrix(self.world.ego_translation_m[frame], self.world.ego_rotation[frame])
        ego_from_sensor = rigid_matrix(self.rig.ego_from_sensor_translation_m[channel],
                                       self.rig.ego_from_sensor_rotation[channel])
        return invert_rigid(global_from_ego @ ego_from_sensor)

    def write(self, dataroot: Path, filenames: list[str], *, images: bool, point_clouds: bool) -> int:
        """Write the files of every camera frame (images) and lidar/radar frame (point_clouds). Returns the
        number of files written."""
        written = 0
        made_dirs: set[Path] = set()
        for frame, filename in enumerate(filenames):
            modality = self.rig.channels[int(self.world.timeline.frame_channel[frame])].modality
            if (modality == "camera" and not images) or (modality != "camera" and not point_clouds):
                continue
            path = dataroot / filename
            if path.parent not in made_dirs:
                path.parent.mkdir(parents=True, exist_ok=True)
                made_dirs.add(path.parent)
            if modality == "camera":
                ok, jpeg = cv2.imencode(".jpg", self.camera_image(frame), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
                if not ok:
                    raise RuntimeError(f"OpenCV could not encode {filename}")
                path.write_bytes(jpeg.tobytes())
            elif modality == "lidar":
                self.lidar_points(frame).astype(np.float32).tofile(path)
            else:
                path.write_bytes(self.radar_pcd(frame))
            written += 1
        return written

    # -- cameras -------------------------------------------------------------------------------------------

    def background(self, channel: int) -> np.ndarray:
        """(height, width, 3) uint8 BGR: a sky gradient above the principal point's row (about the horizon of a
        level camera) and a ground gradient below it; light and unsaturated, unlike the category colours."""
        if channel not in self._backgrounds:
            width_px, height_px = self.rig.channels[channel].size_px
            horizon = int(np.clip(round(self.rig.intrinsic[channel][1, 2]), 1, height_px - 1))
            sky = np.linspace([230, 205, 180], [222, 214, 206], horizon)  # BGR, pale blue to haze
            ground = np.linspace([178, 182, 184], [150, 156, 160], height_px - horizon)  # warm greys
            column = np.round(np.concatenate([sky, ground])).astype(np.uint8)  # (H, 3)
            self._backgrounds[channel] = np.ascontiguousarray(
                np.broadcast_to(column[:, None, :], (height_px, width_px, 3)))
        return self._backgrounds[channel]

    def camera_image(self, frame: int) -> np.ndarray:
        """(height, width, 3) uint8 BGR image with the frame's boxes painted far to near."""
        channel = int(self.world.timeline.frame_channel[frame])
        image = self.background(channel).copy()
        width_px, height_px = self.rig.channels[channel].size_px
        boxes = self.frame_boxes(frame)
        if boxes.category.size == 0:
            return image
        corners_cam = transform_points(self.sensor_from_global(frame),
                                       box_corners(boxes.center_m, boxes.wlh_m, boxes.rotation))  # (B, 8, 3)
        depth = corners_cam[..., 2]
        in_front = (depth >= MIN_DEPTH_M).all(axis=1)
        uv = corners_cam @ self.rig.intrinsic[channel].T  # (B, 8, 3), as view_points(normalize=True)
        uv = uv[..., :2] / np.where(in_front[:, None], depth, 1.0)[..., None]
        lo, hi = uv.min(axis=1), uv.max(axis=1)
        overlaps = (hi[:, 0] >= 0) & (lo[:, 0] < width_px) & (hi[:, 1] >= 0) & (lo[:, 1] < height_px)
        drawn = np.flatnonzero(in_front & overlaps)
        centre_depth = depth.mean(axis=1)
        shift = 4  # sub-pixel vertices: coordinates in 1/16 px
        for b in drawn[np.argsort(-centre_depth[drawn], kind="stable")]:
            hull = cv2.convexHull(np.round(uv[b] * (1 << shift)).astype(np.int32))
            colour = CATEGORY_BGR[boxes.category[b]]
            cv2.fillConvexPoly(image, hull, colour.tolist(), lineType=cv2.LINE_AA, shift=shift)
            cv2.polylines(image, [hull], True, (colour * 0.55).astype(np.int64).tolist(), 2, cv2.LINE_AA, shift)
        return image

    # -- lidar ---------------------------------------------------------------------------------------------

    def _rng(self, frame: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, 2, self.scene_index, frame])

    def lidar_points(self, frame: int) -> np.ndarray:
        """(N, 5) float64 points x, y, z, intensity, ring in the lidar frame."""
        rng = self._rng(frame)
        boxes = self.frame_boxes(frame)
        sensor_from_global = self.sensor_from_global(frame)
        global_from_sensor = invert_rigid(sensor_from_global)
        origin_global = global_from_sensor[:3, 3]

        # Box returns: num_lidar_pts points on the faces that face the sensor, 3% inside the surface.
        count = boxes.num_lidar_pts
        global_from_box = quat_to_matrix(boxes.rotation)  # (B, 3, 3)
        half = 0.5 * boxes.wlh_m[:, [1, 0, 2]]  # (B, 3) half extents along the box x (length), y (width), z
        face_normal_global = np.einsum("bij,fj->bfi", global_from_box,
                                       np.eye(3)[_FACE_AXIS] * _FACE_SIGN[:, None])  # (B, 5, 3)
        face_center_global = boxes.center_m[:, None, :] + face_normal_global * half[:, _FACE_AXIS][..., None]
        facing = np.einsum("bfi,bfi->bf", face_normal_global, face_center_global - origin_global) < 0
        other_extents = np.prod(np.where(np.eye(3, dtype=bool)[_FACE_AXIS][None], 1.0, 2 * half[:, None, :]), axis=2)
        weight = np.where(facing, other_extents, 0.0)  # (B, 5) face areas of facing faces
        valid = weight.sum(axis=1) > 0
        count = np.where(valid, count, 0)
        box_of_point = np.repeat(np.arange(count.size), count)
        cumulative = np.cumsum(weight / np.maximum(weight.sum(axis=1, keepdims=True), 1e-12), axis=1)
        face = (rng.random(box_of_point.size)[:, None] > cumulative[box_of_point]).sum(axis=1).clip(0, 4)
        unit = rng.uniform(-0.97, 0.97, (box_of_point.size, 3))
        unit[np.arange(face.size), _FACE_AXIS[face]] = 0.97 * _FACE_SIGN[face]
        in_box = unit * half[box_of_point]
        box_points = np.einsum("nij,nj->ni", global_from_box[box_of_point], in_box) + boxes.center_m[box_of_point]

        # Ground returns: the lower rings' rays meet the plane z = 0 (global); none under any box.
        elevations = np.deg2rad(np.array(LIDAR_RING_ELEVATIONS_DEG))
        azimuth = rng.uniform(0, 2 * np.pi) + np.linspace(0, 2 * np.pi, GROUND_AZIMUTHS_PER_RING, endpoint=False)
        el, az = np.meshgrid(elevations, azimuth, indexing="ij")
        ring = np.broadcast_to(np.arange(elevations.size)[:, None], el.shape).ravel()
        direction_sensor = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1).reshape(-1, 3)
        direction_global = direction_sensor @ global_from_sensor[:3, :3].T
        with np.errstate(divide="ignore", invalid="ignore"):
            hit_range = -origin_global[2] / direction_global[:, 2]
        hits = (direction_global[:, 2] < -1e-3) & (hit_range > 0) & (hit_range < LIDAR_MAX_RANGE_M)
        hit_range = hit_range * (1.0 + rng.normal(0.0, 0.002, hit_range.size))  # range noise
        ground = origin_global + hit_range[hits, None] * direction_global[hits]
        ground_ring = ring[hits]
        if boxes.center_m.size:
            local = np.einsum("bji,bnj->bni", global_from_box,
                              ground[None, :, :] - boxes.center_m[:, None, :])  # (B, N, 3) in the box frames
            under = ((np.abs(local[..., 0]) <= half[:, None, 0] + 0.2)
                     & (np.abs(local[..., 1]) <= half[:, None, 1] + 0.2)).any(axis=0)
            ground, ground_ring = ground[~under], ground_ring[~under]

        points_global = np.concatenate([box_points, ground])
        points = transform_points(sensor_from_global, points_global)
        elevation = np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]))
        box_ring = np.abs(elevation[:box_points.shape[0], None] - elevations[None, :]).argmin(axis=1)
        intensity = np.r_[rng.integers(20, 121, box_points.shape[0]), rng.integers(1, 21, ground.shape[0])]
        return np.c_[points, intensity, np.r_[box_ring, ground_ring]]

    # -- radar ---------------------------------------------------------------------------------------------

    def radar_pcd(self, frame: int) -> bytes:
        """PCD v0.7 bytes as the devkit's RadarPointCloud.from_file reads them (at least one point)."""
        rng = self._rng(frame)
        boxes = self.frame_boxes(frame)
        centers = transform_points(self.sensor_from_global(frame), boxes.center_m) if boxes.center_m.size \
            else np.zeros((0, 3))
        azimuth = np.arctan2(centers[:, 1], centers[:, 0])
        distance = np.hypot(centers[:, 0], centers[:, 1])
        seen = (boxes.num_radar_pts > 0) & (np.abs(azimuth) <= RADAR_HALF_FOV_RAD) & (distance < RADAR_MAX_RANGE_M)
        per_box = np.minimum(boxes.num_radar_pts[seen], 4)
        box_xy = np.repeat(centers[seen, :2], per_box, axis=0) + rng.normal(0.0, 0.3, (per_box.sum(), 2))
        n_clutter = int(rng.integers(2, 9))
        clutter_az = rng.uniform(-RADAR_HALF_FOV_RAD, RADAR_HALF_FOV_RAD, n_clutter)
        clutter_range = rng.uniform(5.0, RADAR_MAX_RANGE_M, n_clutter)
        clutter_xy = np.c_[clutter_range * np.cos(clutter_az), clutter_range * np.sin(clutter_az)]
        xy = np.concatenate([box_xy, clutter_xy])
        sensor_velocity = self.box_velocity_mps(frame)[seen] @ self.sensor_from_global(frame)[:3, :3].T
        velocity = np.concatenate([np.repeat(sensor_velocity[:, :2], per_box, axis=0), np.zeros((n_clutter, 2))])
        points = np.zeros(xy.shape[0], dtype=_RADAR_DTYPE)
        points["vx"], points["vy"] = velocity[:, 0], velocity[:, 1]
        points["vx_comp"], points["vy_comp"] = velocity[:, 0], velocity[:, 1]
        points["x"], points["y"] = xy[:, 0], xy[:, 1]  # z stays 0, as in the real radar files
        points["dyn_prop"] = 1  # stationary
        points["id"] = np.arange(xy.shape[0])
        points["rcs"] = np.round(rng.uniform(-5.0, 20.0, xy.shape[0]) * 2) / 2
        points["is_quality_valid"] = 1
        points["ambig_state"] = 3  # unambiguous: kept by the devkit's default filters
        points["invalid_state"] = 0  # valid
        points["pdh0"] = 1
        # The devkit's reader asserts that each field ends strictly before the end of the data: one trailing byte.
        return _RADAR_HEADER.format(n=xy.shape[0]).encode("ascii") + points.tobytes() + b"\n"
