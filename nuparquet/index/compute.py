"""Everything the infos hold, as flat arrays over all samples (no dicts yet): keyframe lidar poses, each
camera's `sensor2lidar`, the sweeps, the boxes in the lidar frame and the camera instances."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.errors import InputError
from nuparquet.index.replay import quaternions, transforms
from nuparquet.index.cam_instances import CamInstances, camera_instances
from nuparquet.index.inputs import Inputs
from nuparquet.index.sweeps import sweep_rows


@dataclass
class Computed:
    inputs: Inputs
    lidar_row: np.ndarray  # (S,) keyframe lidar reading of each sample
    cam_row: np.ndarray  # (S, C) keyframe reading of each camera
    cam_s2l_r: np.ndarray  # (S, C, 3, 3) sensor2lidar_rotation
    cam_s2l_t: np.ndarray  # (S, C, 3)
    sweep_owner: np.ndarray  # (W,) sample row, newest first within a sample
    sweep_row: np.ndarray  # (W,) sample_data row
    sweep_s2l_r: np.ndarray  # (W, 3, 3)
    sweep_s2l_t: np.ndarray  # (W, 3)
    ann_order: np.ndarray  # (A,) annotation rows grouped by sample (sample order, then anns order)
    ann_offsets: np.ndarray  # (S + 1,) slice of `ann_order` per sample
    gt_boxes: np.ndarray  # (A, 7) x, y, z, l, w, h, yaw in the keyframe lidar frame, in `ann_order`
    gt_velocity: np.ndarray  # (A, 2) vx, vy in the lidar frame, in `ann_order`
    cam_instances: CamInstances | None


def offsets(owner: np.ndarray, n: int) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=n))]).astype(np.int64)


def compute(inputs: Inputs, cameras: tuple[str, ...], lidar: str, max_sweeps: int, *,
            with_annotations: bool = True, with_cam_instances: bool = True) -> Computed:
    d = inputs.data
    lidar_row = inputs.keyframe[lidar]
    if (lidar_row < 0).any():
        token = inputs.sample_token[np.argmax(lidar_row < 0)]
        raise InputError(f"sample {token} has no {lidar} keyframe: the infos need one per sample (--lidar)")
    cam_row = np.stack([inputs.keyframe[c] for c in cameras], axis=1)
    if (cam_row < 0).any():
        s, c = np.argwhere(cam_row < 0)[0]
        raise InputError(f"sample {inputs.sample_token[s]} has no {cameras[c]} keyframe (--cameras)")

    def to_lidar(rows: np.ndarray, owner: np.ndarray):
        return transforms.sensor_to_lidar(rows, lidar_row[owner], d.sensor_t, d.sensor_q, d.ego_t, d.ego_q)

    s, c = cam_row.shape
    owner = np.repeat(np.arange(s), c)
    r, t = to_lidar(cam_row.reshape(-1), owner)
    sweep_owner, sweep_row = sweep_rows(lidar_row, d.prev, max_sweeps)
    sweep_r, sweep_t = to_lidar(sweep_row, sweep_owner)

    ann_order = np.argsort(inputs.ann_sample, kind="stable")
    # a test version's infos have no gt_* keys, so v1.4.0's update_nuscenes_infos (`if 'gt_boxes' in
    # ori_info_dict`) leaves every v2 entry's instances empty, whatever annotations the dataset holds
    ann_order = ann_order[(inputs.ann_sample[ann_order] >= 0) & with_annotations]
    a_sample = inputs.ann_sample[ann_order]
    lid = lidar_row[a_sample]
    center, orientation = transforms.boxes_to_sensor(inputs.ann_center[ann_order], inputs.ann_rotation[ann_order],
                                                     lid, d.ego_t, d.ego_q, d.sensor_t, d.sensor_q)
    wlh = inputs.ann_size_wlh[ann_order]
    gt_boxes = np.column_stack([center, wlh[:, 1], wlh[:, 0], wlh[:, 2], quaternions.yaw(orientation)])
    velocity = transforms.velocity_to_sensor(inputs.ann_velocity[ann_order, :2], lid, d.ego_q, d.sensor_q)
    return Computed(
        inputs=inputs, lidar_row=lidar_row, cam_row=cam_row, cam_s2l_r=r.reshape(s, c, 3, 3),
        cam_s2l_t=t.reshape(s, c, 3), sweep_owner=sweep_owner, sweep_row=sweep_row, sweep_s2l_r=sweep_r,
        sweep_s2l_t=sweep_t, ann_order=ann_order, ann_offsets=offsets(a_sample, s), gt_boxes=gt_boxes,
        gt_velocity=velocity[:, :2],
        cam_instances=camera_instances(inputs, cameras) if with_annotations and with_cam_instances else None)
