"""The devkit's `nuscenes.utils.data_classes`: `Box`, `LidarPointCloud`, `RadarPointCloud` (and their base
`PointCloud`), with the devkit's attributes, methods and numbers.

A `Box` is the devkit's object: centre, size [w, l, h], a `pyquaternion.Quaternion` orientation, label, score,
velocity, name, token; its methods are the devkit's formulas, operation for operation (see `nuparquet.devkit`).
Point clouds are (d, N) arrays as in the devkit. Files are read by `nuparquet.sources.points`; with a
`nuparquet.devkit.NuScenes`, `from_file_multisweep` also reads frames whose files are absent from the converted
`lidar_points/` and `radar_points/` datasets (`convert --sensors lidar,radar [--sweeps]`). One module, as user code
imports these classes from the devkit's one module.

Longer than our ~300-line norm on purpose: it mirrors a devkit module whose whole surface user code calls, so its
pieces stay where the devkit's users look for them.
"""

from __future__ import annotations

import copy
import os.path as osp
from abc import ABC, abstractmethod
from functools import reduce

import numpy as np
from pyquaternion import Quaternion

from nuparquet.devkit.utils.geometry_utils import transform_matrix, view_points
from nuparquet.sources.points import read_lidar_bin, read_radar_pcd


class PointCloud(ABC):
    """A point cloud as a (d, N) array `points`: rows 0-2 are x, y, z (moved by `translate`, `rotate`,
    `transform`); other rows (intensity, radar fields) are left as they are."""

    def __init__(self, points: np.ndarray):
        assert points.shape[0] == self.nbr_dims(), "Error: Pointcloud points must have format: %d x n" % self.nbr_dims()
        self.points = points

    @staticmethod
    @abstractmethod
    def nbr_dims() -> int:
        """Rows of `points`."""

    @classmethod
    @abstractmethod
    def from_file(cls, file_name: str) -> PointCloud:
        """The point cloud of one sensor file."""

    @classmethod
    def from_file_multisweep(cls, nusc, sample_rec: dict, chan: str, ref_chan: str, nsweeps: int = 5,
                             min_distance: float = 1.0) -> tuple[PointCloud, np.ndarray]:
        """The points of `chan`'s frame of `sample_rec` and of up to `nsweeps - 1` earlier frames, each with the
        points within `min_distance` of its sensor removed, moved into the frame of `ref_chan`'s keyframe of the
        sample (sensor -> ego -> global -> reference ego -> reference sensor, one fused 4x4 per frame), and the
        (1, N) time lag of every point behind the reference, in seconds. As the devkit's; frames come from the
        dataroot's files, or, with a `nuparquet.devkit.NuScenes`, from the converted points when a file is absent.
        """
        points = np.zeros((cls.nbr_dims(), 0), dtype=np.float32 if cls == LidarPointCloud else np.float64)
        all_pc = cls(points)
        all_times = np.zeros((1, 0))

        ref_sd_rec = nusc.get("sample_data", sample_rec["data"][ref_chan])
        ref_pose_rec = nusc.get("ego_pose", ref_sd_rec["ego_pose_token"])
        ref_cs_rec = nusc.get("calibrated_sensor", ref_sd_rec["calibrated_sensor_token"])
        ref_time = 1e-6 * ref_sd_rec["timestamp"]
        ref_from_car = transform_matrix(ref_cs_rec["translation"], Quaternion(ref_cs_rec["rotation"]), inverse=True)
        car_from_global = transform_matrix(ref_pose_rec["translation"], Quaternion(ref_pose_rec["rotation"]),
                                           inverse=True)

        current_sd_rec = nusc.get("sample_data", sample_rec["data"][chan])
        for _ in range(nsweeps):
            current_pc = cls._frame_of(nusc, current_sd_rec)
            current_pc.remove_close(min_distance)

            current_pose_rec = nusc.get("ego_pose", current_sd_rec["ego_pose_token"])
            global_from_car = transform_matrix(current_pose_rec["translation"],
                                               Quaternion(current_pose_rec["rotation"]), inverse=False)
            current_cs_rec = nusc.get("calibrated_sensor", current_sd_rec["calibrated_sensor_token"])
            car_from_current = transform_matrix(current_cs_rec["translation"], Quaternion(current_cs_rec["rotation"]),
                                                inverse=False)
            trans_matrix = reduce(np.dot, [ref_from_car, car_from_global, global_from_car, car_from_current])
            current_pc.transform(trans_matrix)

            time_lag = ref_time - 1e-6 * current_sd_rec["timestamp"]  # positive: the sweep is older
            all_times = np.hstack((all_times, time_lag * np.ones((1, current_pc.nbr_points()))))
            all_pc.points = np.hstack((all_pc.points, current_pc.points))

            if current_sd_rec["prev"] == "":
                break
            current_sd_rec = nusc.get("sample_data", current_sd_rec["prev"])
        return all_pc, all_times

    @classmethod
    def _frame_of(cls, nusc, sd_rec: dict) -> PointCloud:
        """The cloud of one sample_data record: `nusc`'s own reader when it has one (nuparquet's NuScenes: file,
        else converted points), else the file under `nusc.dataroot` (the devkit's NuScenes)."""
        reader = getattr(nusc, "_point_cloud", None)
        if reader is not None:
            return reader(sd_rec, cls)
        return cls.from_file(osp.join(nusc.dataroot, sd_rec["filename"]))

    def nbr_points(self) -> int:
        return self.points.shape[1]

    def subsample(self, ratio: float) -> None:
        """Keep `ratio` of the points, drawn at random with replacement (numpy's global generator, as the devkit)."""
        selected_ind = np.random.choice(np.arange(0, self.nbr_points()), size=int(self.nbr_points() * ratio))
        self.points = self.points[:, selected_ind]

    def remove_close(self, radius: float) -> None:
        """Drop the points with |x| < radius and |y| < radius (a square about the sensor)."""
        x_filt = np.abs(self.points[0, :]) < radius
        y_filt = np.abs(self.points[1, :]) < radius
        self.points = self.points[:, np.logical_not(np.logical_and(x_filt, y_filt))]

    def translate(self, x: np.ndarray) -> None:
        """Add the translation (3,) to x, y, z."""
        for i in range(3):
            self.points[i, :] = self.points[i, :] + x[i]

    def rotate(self, rot_matrix: np.ndarray) -> None:
        """Rotate x, y, z by a (3, 3) matrix."""
        self.points[:3, :] = np.dot(rot_matrix, self.points[:3, :])

    def transform(self, transf_matrix: np.ndarray) -> None:
        """Apply a (4, 4) homogeneous transform to x, y, z."""
        self.points[:3, :] = transf_matrix.dot(np.vstack((self.points[:3, :], np.ones(self.nbr_points()))))[:3, :]

    def render_height(self, ax, view: np.ndarray = np.eye(4), x_lim=(-20, 20), y_lim=(-20, 20),
                      marker_size: float = 1) -> None:
        """Scatter the points on a matplotlib `ax` through `view`, coloured by height (z)."""
        self._render_helper(2, ax, view, x_lim, y_lim, marker_size)

    def render_intensity(self, ax, view: np.ndarray = np.eye(4), x_lim=(-20, 20), y_lim=(-20, 20),
                         marker_size: float = 1) -> None:
        """Scatter the points on a matplotlib `ax` through `view`, coloured by intensity (row 3)."""
        self._render_helper(3, ax, view, x_lim, y_lim, marker_size)

    def _render_helper(self, color_channel: int, ax, view: np.ndarray, x_lim, y_lim, marker_size: float) -> None:
        points = view_points(self.points[:3, :], view, normalize=False)
        ax.scatter(points[0, :], points[1, :], c=self.points[color_channel, :], s=marker_size)
        ax.set_xlim(x_lim[0], x_lim[1])
        ax.set_ylim(y_lim[0], y_lim[1])


class LidarPointCloud(PointCloud):
    """(4, N) float32 x, y, z, intensity in the lidar frame."""

    @staticmethod
    def nbr_dims() -> int:
        return 4

    @classmethod
    def from_file(cls, file_name: str) -> LidarPointCloud:
        """A `.pcd.bin` file of float32 [x, y, z, intensity, ring] records; the ring index is dropped."""
        assert file_name.endswith(".bin"), "Unsupported filetype {}".format(file_name)
        scan = read_lidar_bin(file_name, 5)
        return cls(scan[:, :cls.nbr_dims()].T)


class RadarPointCloud(PointCloud):
    """(18, N) float64: the PCD fields of a nuScenes radar file (x, y, z, dyn_prop, id, rcs, vx, vy, vx_comp,
    vy_comp, is_quality_valid, ambig_state, x_rms, y_rms, invalid_state, pdh0, vx_rms, vy_rms), filtered.

    The filters are class-wide, as in the devkit: a point is kept when its invalid_state (row -4) is in
    `invalid_states`, its dyn_prop (row 3) in `dynprop_states` and its ambig_state (row 11) in `ambig_states`.
    `disable_filters()` keeps every point, `default_filters()` restores [0], range(7), [3].
    """

    invalid_states = [0]
    dynprop_states = range(7)  # [0, 2, 6]: moving objects only
    ambig_states = [3]

    @classmethod
    def disable_filters(cls) -> None:
        """Keep every radar return (changes the class-wide settings)."""
        cls.invalid_states = list(range(18))
        cls.dynprop_states = list(range(8))
        cls.ambig_states = list(range(5))

    @classmethod
    def default_filters(cls) -> None:
        """The devkit's default filters (changes the class-wide settings)."""
        cls.invalid_states = [0]
        cls.dynprop_states = range(7)
        cls.ambig_states = [3]

    @staticmethod
    def nbr_dims() -> int:
        return 18

    @classmethod
    def from_file(cls, file_name: str, invalid_states=None, dynprop_states=None,
                  ambig_states=None) -> RadarPointCloud:
        """A PCD v0.7 binary radar file, filtered by the given states (None: the class-wide ones). A cloud whose
        first point holds a NaN is empty."""
        assert file_name.endswith(".pcd"), "Unsupported filetype {}".format(file_name)
        records = read_radar_pcd(file_name)
        points = np.stack([records[name].astype(np.float64) for name in records.dtype.names])
        return cls._filtered(points, invalid_states, dynprop_states, ambig_states)

    @classmethod
    def _filtered(cls, points: np.ndarray, invalid_states=None, dynprop_states=None,
                  ambig_states=None) -> RadarPointCloud:
        """(F, N) float64 PCD fields -> the devkit's filtered cloud (an empty one when point 0 holds a NaN)."""
        if points.shape[1] == 0 or np.any(np.isnan(points[:, 0])):
            return cls(np.zeros((points.shape[0], 0)))
        invalid_states = cls.invalid_states if invalid_states is None else invalid_states
        dynprop_states = cls.dynprop_states if dynprop_states is None else dynprop_states
        ambig_states = cls.ambig_states if ambig_states is None else ambig_states
        for row, states in ((-4, invalid_states), (3, dynprop_states), (11, ambig_states)):
            points = points[:, _is_in(points[row, :], states)]
        return cls(points)


def _is_in(values: np.ndarray, states) -> np.ndarray:
    """(N,) bool: `value in states` for each value, Python's membership (0.0 is in [0]; NaN in nothing)."""
    states = list(states)
    if all(isinstance(s, (int, float, np.integer, np.floating)) and not isinstance(s, bool) for s in states):
        return np.isin(values, np.asarray(states, dtype=np.float64))
    return np.array([v in states for v in values.tolist()], dtype=bool)


class Box:
    """A 3D box: `center` (3,), `wlh` (3,) [width, length, height], `orientation` (pyquaternion.Quaternion),
    `label`, `score`, `velocity` (3,), `name`, `token`. x points forward, y left, z up in the box's frame."""

    def __init__(self, center, size, orientation: Quaternion, label: int = np.nan, score: float = np.nan,
                 velocity=(np.nan, np.nan, np.nan), name: str | None = None, token: str | None = None):
        assert not np.any(np.isnan(center))
        assert not np.any(np.isnan(size))
        assert len(center) == 3
        assert len(size) == 3
        assert type(orientation) == Quaternion  # noqa: E721 - the devkit's exact check

        self.center = np.array(center)
        self.wlh = np.array(size)
        self.orientation = orientation
        self.label = int(label) if not np.isnan(label) else label
        self.score = float(score) if not np.isnan(score) else score
        self.velocity = np.array(velocity)
        self.name = name
        self.token = token

    @classmethod
    def _of(cls, center: np.ndarray, wlh: np.ndarray, orientation: Quaternion, name: str | None,
            token: str | None) -> Box:
        """A box with the attributes `Box(center, wlh, orientation, name=name, token=token)` gives, without its
        checks (nuparquet's own boxes: converted data is checked at conversion)."""
        box = cls.__new__(cls)
        box.center = center
        box.wlh = wlh
        box.orientation = orientation
        box.label = np.nan
        box.score = np.nan
        box.velocity = np.array((np.nan, np.nan, np.nan))
        box.name = name
        box.token = token
        return box

    def __eq__(self, other) -> bool:
        center = np.allclose(self.center, other.center)
        wlh = np.allclose(self.wlh, other.wlh)
        orientation = np.allclose(self.orientation.elements, other.orientation.elements)
        label = (self.label == other.label) or (np.isnan(self.label) and np.isnan(other.label))
        score = (self.score == other.score) or (np.isnan(self.score) and np.isnan(other.score))
        vel = (np.allclose(self.velocity, other.velocity)
               or (np.all(np.isnan(self.velocity)) and np.all(np.isnan(other.velocity))))
        return center and wlh and orientation and label and score and vel

    __hash__ = None  # mutable and compared by value, as the devkit's (which defines __eq__ only)

    def __repr__(self) -> str:
        repr_str = ("label: {}, score: {:.2f}, xyz: [{:.2f}, {:.2f}, {:.2f}], wlh: [{:.2f}, {:.2f}, {:.2f}], "
                    "rot axis: [{:.2f}, {:.2f}, {:.2f}], ang(degrees): {:.2f}, ang(rad): {:.2f}, "
                    "vel: {:.2f}, {:.2f}, {:.2f}, name: {}, token: {}")
        return repr_str.format(self.label, self.score, self.center[0], self.center[1], self.center[2], self.wlh[0],
                               self.wlh[1], self.wlh[2], self.orientation.axis[0], self.orientation.axis[1],
                               self.orientation.axis[2], self.orientation.degrees, self.orientation.radians,
                               self.velocity[0], self.velocity[1], self.velocity[2], self.name, self.token)

    @property
    def rotation_matrix(self) -> np.ndarray:
        """(3, 3) the orientation's rotation matrix."""
        return self.orientation.rotation_matrix

    def translate(self, x: np.ndarray) -> None:
        """Move the centre by (3,) `x`."""
        self.center += x

    def rotate(self, quaternion: Quaternion) -> None:
        """Rotate the box about the origin: centre, orientation and velocity."""
        self.center = np.dot(quaternion.rotation_matrix, self.center)
        self.orientation = quaternion * self.orientation
        self.velocity = np.dot(quaternion.rotation_matrix, self.velocity)

    def corners(self, wlh_factor: float = 1.0) -> np.ndarray:
        """(3, 8) corners, the size scaled by `wlh_factor`: the first four face forward (+x), the last four back."""
        w, l, h = self.wlh * wlh_factor
        x_corners = l / 2 * np.array([1, 1, 1, 1, -1, -1, -1, -1])
        y_corners = w / 2 * np.array([1, -1, -1, 1, 1, -1, -1, 1])
        z_corners = h / 2 * np.array([1, 1, -1, -1, 1, 1, -1, -1])
        corners = np.dot(self.orientation.rotation_matrix, np.vstack((x_corners, y_corners, z_corners)))
        x, y, z = self.center
        corners[0, :] = corners[0, :] + x
        corners[1, :] = corners[1, :] + y
        corners[2, :] = corners[2, :] + z
        return corners

    def bottom_corners(self) -> np.ndarray:
        """(3, 4) the bottom corners, the two front ones first."""
        return self.corners()[:, [2, 3, 7, 6]]

    def render(self, axis, view: np.ndarray = np.eye(3), normalize: bool = False, colors=("b", "r", "k"),
               linewidth: float = 2) -> None:
        """Draw the box on a matplotlib `axis` through `view` (an intrinsic with `normalize=True` for an image):
        front face in colors[0], back face in colors[1], sides in colors[2], and a line marking the front."""
        corners = view_points(self.corners(), view, normalize=normalize)[:2, :]

        def draw_rect(selected_corners, color):
            prev = selected_corners[-1]
            for corner in selected_corners:
                axis.plot([prev[0], corner[0]], [prev[1], corner[1]], color=color, linewidth=linewidth)
                prev = corner

        for i in range(4):
            axis.plot([corners.T[i][0], corners.T[i + 4][0]], [corners.T[i][1], corners.T[i + 4][1]],
                      color=colors[2], linewidth=linewidth)
        draw_rect(corners.T[:4], colors[0])
        draw_rect(corners.T[4:], colors[1])
        center_bottom_forward = np.mean(corners.T[2:4], axis=0)
        center_bottom = np.mean(corners.T[[2, 3, 7, 6]], axis=0)
        axis.plot([center_bottom[0], center_bottom_forward[0]], [center_bottom[1], center_bottom_forward[1]],
                  color=colors[0], linewidth=linewidth)

    def render_cv2(self, im: np.ndarray, view: np.ndarray = np.eye(3), normalize: bool = False,
                   colors=((0, 0, 255), (255, 0, 0), (155, 155, 155)), linewidth: int = 2) -> None:
        """Draw the box on a BGR image `im` with OpenCV; `colors` are RGB (front, back, sides)."""
        import cv2

        corners = view_points(self.corners(), view, normalize=normalize)[:2, :]

        def draw_rect(selected_corners, color):
            prev = selected_corners[-1]
            for corner in selected_corners:
                cv2.line(im, (int(prev[0]), int(prev[1])), (int(corner[0]), int(corner[1])), color, linewidth)
                prev = corner

        for i in range(4):
            cv2.line(im, (int(corners.T[i][0]), int(corners.T[i][1])),
                     (int(corners.T[i + 4][0]), int(corners.T[i + 4][1])), colors[2][::-1], linewidth)
        draw_rect(corners.T[:4], colors[0][::-1])
        draw_rect(corners.T[4:], colors[1][::-1])
        center_bottom_forward = np.mean(corners.T[2:4], axis=0)
        center_bottom = np.mean(corners.T[[2, 3, 7, 6]], axis=0)
        cv2.line(im, (int(center_bottom[0]), int(center_bottom[1])),
                 (int(center_bottom_forward[0]), int(center_bottom_forward[1])), colors[0][::-1], linewidth)

    def copy(self) -> Box:
        return copy.deepcopy(self)
