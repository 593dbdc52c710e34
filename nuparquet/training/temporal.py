"""BEVFormer's temporal context (fundamentalvision/BEVFormer, `projects/mmdet3d_plugin/datasets/
nuscenes_dataset.py`, `CustomNuScenesDataset`): the CAN bus vector as its `get_data_info` patches it, the frames
of a `queue_length` queue, and its `union2one` over them (`prev_bev_exists`, the CAN bus made relative)."""

from __future__ import annotations

import numpy as np

from nuparquet.geometry import heading_from_quaternions


def patched_can_bus(can_bus: np.ndarray, ego_t: np.ndarray, ego_q: np.ndarray) -> np.ndarray:
    """(S, 18) the converter's `can_bus` vectors (S, 18) as `get_data_info` hands them on: the position replaced by
    the lidar keyframe's ego pose (`ego2global_translation`), values 3..6 by its rotation's w four times (its
    `can_bus[3:7] = Quaternion(...)` assigns `float(quaternion)`, pyquaternion's real part, to each: the quirk
    every BEVFormer model was trained with), then the pose's yaw (the devkit's `quaternion_yaw`) in [0, 360)
    degrees as the last value and in radians before it."""
    out = np.array(can_bus, dtype=np.float64)
    out[:, :3] = ego_t
    out[:, 3:7] = np.asarray(ego_q)[:, :1]
    patch_angle = heading_from_quaternions(ego_q) / np.pi * 180
    patch_angle = np.where(patch_angle < 0, patch_angle + 360, patch_angle)
    out[:, -2] = patch_angle / 180 * np.pi
    out[:, -1] = patch_angle
    return out


def queue_rows(row: int, queue_length: int) -> list[int]:
    """The rows of the queue ending at `row`, oldest first: the `queue_length - 1` rows before it and itself,
    clamped at 0 as `prepare_train_data`'s `max(0, i)` (BEVFormer's test-time choice; its training draws
    `queue_length - 1` of the `queue_length` previous rows at random, left out: an augmentation)."""
    return [max(0, i) for i in range(row - queue_length + 1, row + 1)]


def union2one(scene_tokens: list[str], can_bus: list[np.ndarray | None]) -> tuple[list[bool], list[np.ndarray | None]]:
    """`union2one`'s per-frame metas: `prev_bev_exists` (False where the scene differs from the previous frame's,
    and for the first) and, for frames with a CAN bus vector, the vector with position and angle [deg] made
    relative to the previous frame's (zero at a scene's first frame in the queue)."""
    exists, out = [], []
    prev_scene, prev_pos, prev_angle = None, None, None
    for scene, vector in zip(scene_tokens, can_bus):
        vector = None if vector is None else vector.copy()
        if scene != prev_scene:
            exists.append(False)
            prev_scene = scene
            if vector is not None:
                prev_pos, prev_angle = vector[:3].copy(), vector[-1]
                vector[:3] = 0
                vector[-1] = 0
        else:
            exists.append(True)
            if vector is not None:
                pos, angle = vector[:3].copy(), vector[-1]
                vector[:3] -= prev_pos
                vector[-1] -= prev_angle
                prev_pos, prev_angle = pos, angle
        out.append(vector)
    return exists, out
