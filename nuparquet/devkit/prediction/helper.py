"""nuscenes-devkit 1.2.0's `nuscenes.prediction.helper`: `PredictHelper` answered from the converted
`tables/sample_annotation` and `tables/sample`, indexed once per helper as arrays (each annotation's row, its
`prev`/`next` rows, its sample's timestamp), and the module's coordinate functions.

The windows (which records an agent's past or future holds) are walked by `frames.annotation_chains`, for every
agent of a call at once, with the devkit's rule kept exactly. Records (`just_xy=False`) are the
`NuScenes.get('sample_annotation', token)` dicts.

Where the devkit's numbers are the point, its arithmetic is reproduced operation for operation, batched through
the same BLAS calls numpy makes for one item (`np.matmul` of stacked matrices calls the `dgemm`/`dgemv` that
`np.dot` calls for each): the yaw is pyquaternion's `Q(q) @ Qbar(q)^T` rotation matrix times `[1, 0, 0]`
(`nuscenes.eval.common.utils.quaternion_yaw`), the agent-frame rotation is the 2x2 `dgemm` of
`convert_global_coords_to_local` per window length, and the velocity's norm is the `ddot` of
`np.linalg.norm` (`geometry.dots`). So results are bit-equal to the devkit's on the machine that runs both.

Some 300 lines: the devkit's module is one class and its coordinate functions, kept together at its import path.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import polars as pl
from pyquaternion import Quaternion

from nuparquet.frames.annotation_chains import DANGLING, NONE, AnnotationChains
from nuparquet.geometry.dots import rowwise_norm
from nuparquet.geometry.quaternions import normalise_quaternions

Record = dict[str, Any]


def quaternion_yaw(q: Quaternion) -> float:
    """The devkit's `nuscenes.eval.common.utils.quaternion_yaw`: the heading of R @ [1, 0, 0]."""
    v = np.dot(q.rotation_matrix, np.array([1, 0, 0]))
    return np.arctan2(v[1], v[0])


def angle_of_rotation(yaw: float) -> float:
    """The angle to rotate by so that `yaw` (from the x axis) points along the y axis (pi / 2); works on arrays."""
    return (np.pi / 2) + np.sign(-yaw) * np.abs(yaw)


def make_2d_rotation_matrix(angle_in_radians: float) -> np.ndarray:
    """(2, 2) counter-clockwise rotation in the x-y plane."""
    return np.array([[np.cos(angle_in_radians), -np.sin(angle_in_radians)],
                     [np.sin(angle_in_radians), np.cos(angle_in_radians)]])


def convert_global_coords_to_local(coordinates: np.ndarray, translation, rotation) -> np.ndarray:
    """(N, 2) global x, y into the frame at `translation` (x, y, z) turned by the z rotation `rotation` [w, x, y, z]
    so that its heading is the y axis; the devkit's operations."""
    yaw = angle_of_rotation(quaternion_yaw(Quaternion(rotation)))
    transform = make_2d_rotation_matrix(angle_in_radians=yaw)
    coords = (coordinates - np.atleast_2d(np.array(translation)[:2])).T
    return np.dot(transform, coords).T[:, :2]


def convert_local_coords_to_global(coordinates: np.ndarray, translation, rotation) -> np.ndarray:
    """(N, 2) the inverse of `convert_global_coords_to_local`; the devkit's operations."""
    yaw = angle_of_rotation(quaternion_yaw(Quaternion(rotation)))
    transform = make_2d_rotation_matrix(angle_in_radians=-yaw)
    return np.dot(transform, coordinates.T).T[:, :2] + np.atleast_2d(np.array(translation)[:2])


def quaternion_yaws(q_wxyz: np.ndarray) -> np.ndarray:
    """(N,) `quaternion_yaw(Quaternion(q))` of (N, 4) quaternions, bit for bit: pyquaternion's normalisation, its
    4x4 product `Q(q) @ Qbar(q)^T` and the 3x3 times [1, 0, 0], each through the BLAS call numpy makes for one."""
    w, x, y, z = np.moveaxis(normalise_quaternions(q_wxyz), -1, 0)
    q_matrix = np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, -z, y], -1),
                         np.stack([y, z, w, -x], -1), np.stack([z, -y, x, w], -1)], -2)
    q_bar_matrix = np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, z, -y], -1),
                             np.stack([y, -z, w, x], -1), np.stack([z, y, -x, w], -1)], -2)
    rotation = np.matmul(q_matrix, np.swapaxes(q_bar_matrix, -1, -2))[:, 1:, 1:]
    v = np.matmul(rotation, np.array([1.0, 0.0, 0.0]))
    return np.arctan2(v[:, 1], v[:, 0])


def _angle_diffs(x: np.ndarray, y: np.ndarray, period: float) -> np.ndarray:
    """(N,) the devkit's `angle_diff(x, y, period)` (numpy's float remainder, as on its np.float64 yaws)."""
    diff = (x - y + period / 2) % period - period / 2
    return np.where(diff > np.pi, diff - (2 * np.pi), diff)


class PredictHelper:
    """The devkit's `PredictHelper(nusc)` over a `nuparquet.devkit.NuScenes` (its converted `Dataset`)."""

    def __init__(self, nusc):
        self.data = nusc
        chains, annotations = AnnotationChains.of(nusc._dataset, "rotation")
        self._chains = chains
        n = annotations.height
        self._tokens = chains.tokens
        self._sample_tokens = chains.sample_tokens
        self._instance_tokens = chains.instance_tokens
        self._translation = chains.translation
        # (N, 4) as stored: the devkit's np.array of the record's list gives these numbers
        self._rotation = np.asarray(annotations["rotation"].to_numpy(), dtype=np.float64).reshape(n, 4)
        self._prev = chains.prev
        self._sample_of = {token: i for i, token in enumerate(chains.sample_index["token"].to_list())}
        self._sample_row = chains.sample_row  # (N,) row of each annotation's sample, DANGLING when none
        self._sample_timestamp = chains.sample_timestamp
        # (sample_token, instance_token) -> row: the devkit's mapping, a later record winning
        self._row_of = dict(zip(zip(annotations["sample_token"].to_list(), annotations["instance_token"].to_list()),
                                range(n)))
        # sample token -> its annotations' rows in file order (the devkit's sample['anns'])
        grouped = (pl.DataFrame({"sample_token": annotations["sample_token"], "row": np.arange(n, dtype=np.int64)})
                   .group_by("sample_token", maintain_order=True).agg("row"))
        self._rows_of_sample = dict(zip(grouped["sample_token"].to_list(),
                                        (np.asarray(r, dtype=np.int64) for r in grouped["row"].to_list())))

    # --- lookups -----------------------------------------------------------------------------------------------

    def _row(self, instance_token: str, sample_token: str) -> int:
        return self._row_of[(sample_token, instance_token)]

    def _sample_rows(self, sample_token: str) -> np.ndarray:
        if sample_token not in self._sample_of:
            raise KeyError(sample_token)
        return self._rows_of_sample.get(sample_token, np.zeros(0, dtype=np.int64))

    def _records(self, rows) -> list[Record]:
        return [self.data.get("sample_annotation", self._tokens[row]) for row in rows]

    def get_sample_annotation(self, instance_token: str, sample_token: str) -> Record:
        """The sample_annotation record of an instance at a sample."""
        return self.data.get("sample_annotation", self._tokens[self._row(instance_token, sample_token)])

    def get_annotations_for_sample(self, sample_token: str) -> list[Record]:
        """The sample's annotation records, in the devkit's `sample['anns']` order."""
        return self._records(self._sample_rows(sample_token))

    # --- windows -----------------------------------------------------------------------------------------------

    def _xy(self, start_rows: np.ndarray, windows: list[np.ndarray], in_agent_frame: bool) -> list[np.ndarray]:
        """Each window's (L, 2) x, y (the devkit's `np.array([])` of shape (0,) for an empty one), turned into its
        start's frame when `in_agent_frame`: one stacked `dgemm` per window length, as the devkit's `np.dot`."""
        out: list[np.ndarray] = [np.array([]) for _ in windows]
        lengths = np.array([len(w) for w in windows], dtype=np.int64)
        if in_agent_frame and (lengths > 0).any():
            yaw = angle_of_rotation(quaternion_yaws(self._rotation[start_rows[lengths > 0]]))
            cos, sin = np.cos(yaw), np.sin(yaw)
            transform = np.stack([np.stack([cos, -sin], -1), np.stack([sin, cos], -1)], -2)  # (A', 2, 2)
            agent_transform = dict(zip(np.flatnonzero(lengths > 0), transform))
        for length in np.unique(lengths[lengths > 0]):
            agents = np.flatnonzero(lengths == length)
            coords = self._translation[np.stack([windows[a] for a in agents])][..., :2]  # (G, L, 2)
            if in_agent_frame:
                local = coords - self._translation[start_rows[agents], None, :2]
                turned = np.matmul(np.stack([agent_transform[a] for a in agents]), np.swapaxes(local, -1, -2))
                coords = np.swapaxes(turned, -1, -2)
            for a, xy in zip(agents, coords):
                out[a] = xy
        return out

    def _past_or_future(self, start_rows: np.ndarray, seconds: float, in_agent_frame: bool, direction: str,
                        just_xy: bool) -> list:
        windows = self._chains.windows(start_rows, seconds, direction)
        if not just_xy:
            return [self._records(w) for w in windows]
        return self._xy(start_rows, windows, in_agent_frame)

    def get_future_for_agent(self, instance_token: str, sample_token: str, seconds: float, in_agent_frame: bool,
                             just_xy: bool = True):
        """(L, 2) the agent's future x, y over `seconds` (or its records when not `just_xy`), nearest first."""
        start = np.array([self._row(instance_token, sample_token)])
        return self._past_or_future(start, seconds, in_agent_frame, "next", just_xy)[0]

    def get_past_for_agent(self, instance_token: str, sample_token: str, seconds: float, in_agent_frame: bool,
                           just_xy: bool = True):
        """(L, 2) the agent's past x, y over `seconds` (or its records when not `just_xy`), nearest first."""
        start = np.array([self._row(instance_token, sample_token)])
        return self._past_or_future(start, seconds, in_agent_frame, "prev", just_xy)[0]

    def _for_sample(self, sample_token: str, seconds: float, in_agent_frame: bool, direction: str,
                    just_xy: bool) -> dict:
        rows = self._sample_rows(sample_token)
        # the devkit looks each annotation up again by (sample, instance): a later duplicate's record wins
        instances = self._instance_tokens[rows].tolist()
        starts = np.array([self._row_of[(sample_token, i)] for i in instances], dtype=np.int64)
        return dict(zip(instances, self._past_or_future(starts, seconds, in_agent_frame, direction, just_xy)))

    def get_future_for_sample(self, sample_token: str, seconds: float, in_agent_frame: bool, just_xy: bool = True):
        """instance token -> every agent of the sample's `get_future_for_agent`."""
        return self._for_sample(sample_token, seconds, in_agent_frame, "next", just_xy)

    def get_past_for_sample(self, sample_token: str, seconds: float, in_agent_frame: bool, just_xy: bool = True):
        """instance token -> every agent of the sample's `get_past_for_agent`."""
        return self._for_sample(sample_token, seconds, in_agent_frame, "prev", just_xy)

    # --- rates -------------------------------------------------------------------------------------------------

    def _with_prev(self, rows: np.ndarray, sample_rows: np.ndarray, max_time_diff: float):
        """For (A,) annotation rows seen at (A,) sample rows: their prev rows, the time differences (s) and which
        have a prev within `max_time_diff` (the devkit's `_compute_diff_between_sample_annotations` gate)."""
        prev = self._prev[rows]
        has_prev = prev != NONE
        if (prev[has_prev] == DANGLING).any():
            raise KeyError("sample_annotation prev names no record")
        prev = np.where(has_prev, prev, rows)
        current_time = 1e-6 * self._sample_timestamp[sample_rows]
        prev_time = 1e-6 * self._chains.checked_timestamps(prev)
        time_diff = current_time - prev_time
        return prev, time_diff, has_prev & (time_diff <= max_time_diff)

    def _velocities(self, rows: np.ndarray, sample_rows: np.ndarray, max_time_diff: float) -> np.ndarray:
        prev, time_diff, valid = self._with_prev(rows, sample_rows, max_time_diff)
        diff = (self._translation[rows] - self._translation[prev]) / time_diff[:, None]
        return np.where(valid, rowwise_norm(diff[:, :2]), np.nan)

    def _sample_row_of(self, sample_token: str) -> np.ndarray:
        return np.array([self._sample_of[sample_token]])

    def get_velocity_for_agent(self, instance_token: str, sample_token: str, max_time_diff: float = 1.5) -> float:
        """Speed (m/s) from the previous annotation; NaN without one or when it is more than `max_time_diff` s old."""
        row = np.array([self._row(instance_token, sample_token)])
        with np.errstate(divide="ignore", invalid="ignore"):
            return self._velocities(row, self._sample_row_of(sample_token), max_time_diff)[0]

    def get_heading_change_rate_for_agent(self, instance_token: str, sample_token: str,
                                          max_time_diff: float = 1.5) -> float:
        """Yaw rate (rad/s) from the previous annotation; NaN as `get_velocity_for_agent`."""
        row = np.array([self._row(instance_token, sample_token)])
        prev, time_diff, valid = self._with_prev(row, self._sample_row_of(sample_token), max_time_diff)
        if not valid[0]:
            return np.nan
        yaws = quaternion_yaws(self._rotation[np.concatenate([row, prev])])
        return _angle_diffs(yaws[:1], yaws[1:], period=2 * np.pi)[0] / time_diff[0]

    def get_acceleration_for_agent(self, instance_token: str, sample_token: str, max_time_diff: float = 1.5) -> float:
        """Change of speed (m/s^2) from the previous annotation, both speeds with the devkit's default 1.5 s gate."""
        row = np.array([self._row(instance_token, sample_token)])
        prev, time_diff, valid = self._with_prev(row, self._sample_row_of(sample_token), max_time_diff)
        if not valid[0]:
            return np.nan
        # the devkit takes the speeds at the annotations' own samples, by (sample, instance) again
        prev_sample_token = self._sample_tokens[prev[0]]
        rows = np.array([row[0], self._row(instance_token, prev_sample_token)])
        sample_rows = np.array([self._sample_of[sample_token], self._sample_of[prev_sample_token]])
        with np.errstate(divide="ignore", invalid="ignore"):
            speeds = self._velocities(rows, sample_rows, 1.5)
        return (speeds[0] - speeds[1]) / time_diff[0]

    def get_map_name_from_sample_token(self, sample_token: str) -> str:
        """The location (map name) of the sample's log."""
        sample = self.data.get("sample", sample_token)
        scene = self.data.get("scene", sample["scene_token"])
        return self.data.get("log", scene["log_token"])["location"]
