"""mmdetection3d v1.4.0's transforms of the infos' arrays, operation for operation: the close-point filter of
`LoadPointsFromMultiSweeps`, the boxes of `NuScenesDataset.parse_ann_info`, and the camera matrices BEVFusion's
`BEVLoadMultiViewImageFromFiles` builds."""

from __future__ import annotations

import numpy as np


def remove_close(points: np.ndarray, radius: float = 1.0) -> np.ndarray:
    """(P', D) the points of `points` (P, D) outside the square |x| < radius and |y| < radius (mmdetection3d's
    `LoadPointsFromMultiSweeps._remove_close`)."""
    close = (np.abs(points[:, 0]) < radius) & (np.abs(points[:, 1]) < radius)
    return points[~close]


def camera_matrices(cam2img: np.ndarray, lidar2cam: np.ndarray) -> dict:
    """cam2img, lidar2cam, cam2lidar, lidar2img (each (C, 4, 4)) from the infos' `cam2img` (C, 3, 3) and
    `lidar2cam` (C, 4, 4), one camera at a time as BEVFusion's `BEVLoadMultiViewImageFromFiles` computes them (its
    2-D float32 products, so the BLAS path is the same)."""
    out: dict = {"cam2img": [], "lidar2cam": [], "cam2lidar": [], "lidar2img": []}
    for intrinsic, from_lidar in zip(cam2img.tolist(), lidar2cam.tolist()):  # the infos' lists
        lidar2cam_array = np.array(from_lidar).astype(np.float32)
        rot, trans = lidar2cam_array[:3, :3], lidar2cam_array[:3, 3:4]
        cam2lidar = np.eye(4)
        cam2lidar[:3, :3] = rot.T
        cam2lidar[:3, 3:4] = -1 * np.matmul(rot.T, trans.reshape(3, 1))
        cam2img_array = np.eye(4).astype(np.float32)
        cam2img_array[:3, :3] = np.array(intrinsic).astype(np.float32)
        out["cam2img"].append(cam2img_array)
        out["lidar2cam"].append(from_lidar)
        out["cam2lidar"].append(cam2lidar)
        out["lidar2img"].append(cam2img_array @ lidar2cam_array)
    return {key: np.stack(values) if values else np.zeros((0, 4, 4)) for key, values in out.items()}


def gt_bboxes_3d(box: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """(A, 9) float32 from the infos' `bbox_3d` (A, 7) (gravity centre) and `velocity` (A, 2), as mmdetection3d's
    `NuScenesDataset.parse_ann_info` makes them: NaN velocity set to 0, concatenated, then
    `LiDARInstance3DBoxes(origin=(0.5, 0.5, 0.5))` in float32 moves the centre to the bottom."""
    velocity = velocity.copy()
    velocity[np.isnan(velocity[:, 0])] = 0.0
    boxes = np.concatenate([box, velocity], axis=-1).astype(np.float32).reshape(-1, 9)
    boxes[:, 2] += boxes[:, 5] * np.float32(-0.5)
    return boxes
