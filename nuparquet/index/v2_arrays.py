"""Everything one split's v2 infos hold, as flat arrays with offsets (no dicts): what `records.v2_infos`
turns into the pickle's objects and `parquet.infos_table` into Arrow columns, so the two carry the same
values by construction. Matrices are gathered per use from ones computed once per sensor reading."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from nuparquet.index.replay import transforms
from nuparquet.index.compute import Computed, offsets
from nuparquet.index.labels import label_of, mapped_names


def _basename(path: str) -> str:
    return path.rsplit("/", 1)[-1]  # PurePosixPath(path).name for the tables' relative file names


@dataclass
class V2Arrays:
    cameras: tuple[str, ...]
    token: np.ndarray  # (S,) str
    timestamp_s: np.ndarray  # (S,)
    ego2global: np.ndarray  # (S, 4, 4) float32 (float64 when corrected)
    ego2global_f64: np.ndarray  # (S, 4, 4)
    lidar_path: list  # (S,) basenames
    lidar2ego: np.ndarray  # (S, 4, 4)
    lidar2ego_f64: np.ndarray  # (S, 4, 4)
    cam_path: list  # (S * C,) basenames, sample-major
    cam2img: np.ndarray  # (S, C, 3, 3)
    cam2ego: np.ndarray  # (S, C, 4, 4)
    cam_token: np.ndarray  # (S, C) str
    cam_timestamp_s: np.ndarray  # (S, C)
    lidar2cam: np.ndarray  # (S, C, 4, 4)
    sweep_offsets: np.ndarray  # (S + 1,)
    sweep_timestamp_s: np.ndarray  # (W,)
    sweep_ego2global: np.ndarray  # (W, 4, 4)
    sweep_path: list  # (W,)
    sweep_lidar2ego: np.ndarray  # (W, 4, 4)
    sweep_lidar2sensor: np.ndarray  # (W, 4, 4)
    sweep_token: np.ndarray  # (W,) str
    ann_offsets: np.ndarray  # (S + 1,)
    ann_label: np.ndarray  # (A,) int64, -1 outside the ten classes
    ann_name: np.ndarray  # (A,) object: the class, or the category name when unmapped
    ann_box: np.ndarray  # (A, 7)
    ann_valid: np.ndarray  # (A,) bool
    ann_num_lidar_pts: np.ndarray  # (A,) int64
    ann_num_radar_pts: np.ndarray  # (A,) int64
    ann_velocity: np.ndarray  # (A, 2)
    semantic_mask_path: list | None  # (S,) lidarseg label file basenames; None without lidarseg (or in test)
    ci_offsets: np.ndarray | None  # (S * C + 1,) camera instances per (sample, camera), sample-major
    ci_label: np.ndarray | None  # (K,)
    ci_bbox: np.ndarray | None  # (K, 4)
    ci_bbox_3d: np.ndarray | None  # (K, 7)
    ci_velocity: np.ndarray | None  # (K, 2)
    ci_center_2d: np.ndarray | None  # (K, 2)
    ci_depth: np.ndarray | None  # (K,)
    ci_attr_label: np.ndarray | None  # (K,)

    def slice(self, lo: int, hi: int) -> V2Arrays:
        """Samples [lo, hi) with their sweeps, instances and camera instances (offsets rebased)."""
        n_cam = len(self.cameras)
        per_sample = ("token", "timestamp_s", "ego2global", "ego2global_f64", "lidar_path", "lidar2ego",
                      "lidar2ego_f64", "cam2img", "cam2ego", "cam_token", "cam_timestamp_s", "lidar2cam")
        out = {name: getattr(self, name)[lo:hi] for name in per_sample}
        out["cam_path"] = self.cam_path[lo * n_cam:hi * n_cam]
        out["semantic_mask_path"] = None if self.semantic_mask_path is None else self.semantic_mask_path[lo:hi]
        segments = (("sweep_offsets", lo, hi, ("sweep_timestamp_s", "sweep_ego2global", "sweep_path",
                                               "sweep_lidar2ego", "sweep_lidar2sensor", "sweep_token")),
                    ("ann_offsets", lo, hi, ("ann_label", "ann_name", "ann_box", "ann_valid", "ann_num_lidar_pts",
                                             "ann_num_radar_pts", "ann_velocity")),
                    ("ci_offsets", lo * n_cam, hi * n_cam, ("ci_label", "ci_bbox", "ci_bbox_3d", "ci_velocity",
                                                            "ci_center_2d", "ci_depth", "ci_attr_label")))
        for offsets_name, a, b, names in segments:
            offs = getattr(self, offsets_name)
            if offs is None:
                out[offsets_name] = None
                out.update(dict.fromkeys(names))
                continue
            out[offsets_name] = offs[a:b + 1] - offs[a]
            out.update({name: getattr(self, name)[offs[a]:offs[b]] for name in names})
        return V2Arrays(cameras=self.cameras, **out)


def gather_segments(segment_offsets: np.ndarray, picked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(items, new offsets): the items of segments `picked` (in that order) of a segmented array."""
    lengths = segment_offsets[picked + 1] - segment_offsets[picked]
    new = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    items = np.repeat(segment_offsets[picked] - new[:-1], lengths) + np.arange(new[-1])
    return items, new


def v2_arrays(c: Computed, samples: np.ndarray, cameras: tuple[str, ...], prefix: str, *,
              corrected: bool = False, mask_files: np.ndarray | None = None) -> V2Arrays:
    """The arrays of the samples `samples` (rows, in output order). `corrected`: float64 matrices and sweep
    paths without the data prefix (the reference's quirks undone). `mask_files` (S,): lidarseg label files of
    all samples (`Path(v1 path).name` becomes `pts_semantic_mask_path`), None without lidarseg."""
    inp, d = c.inputs, c.inputs.data
    n = len(inp.sample_token)
    lid, cam = c.lidar_row[samples], c.cam_row[samples]
    sweeps, sweep_offsets = gather_segments(offsets(c.sweep_owner, n), samples)
    sweep_row = c.sweep_row[sweeps]

    used, where = np.unique(np.concatenate([lid, cam.ravel(), sweep_row]), return_inverse=True)
    ego64 = transforms.pose_matrix_f32(d.ego_q[used], d.ego_t[used], f32=False)
    sensor64 = transforms.pose_matrix_f32(d.sensor_q[used], d.sensor_t[used], f32=False)
    ego, sensor = (ego64, sensor64) if corrected else (ego64.astype(np.float32), sensor64.astype(np.float32))
    at_lid, at_cam, at_sweep = np.split(where, [len(lid), len(lid) + cam.size])
    at_cam = at_cam.reshape(cam.shape)

    f32 = not corrected
    anns, ann_offsets = gather_segments(c.ann_offsets, samples)
    rows = c.ann_order[anns]
    categories = inp.ann_category[rows]
    out = V2Arrays(
        cameras=cameras, token=inp.sample_token[samples], timestamp_s=inp.sample_timestamp_us[samples] / 1e6,
        ego2global=ego[at_lid], ego2global_f64=ego64[at_lid],
        lidar_path=[_basename(p) for p in d.filename[lid].tolist()],
        lidar2ego=sensor[at_lid], lidar2ego_f64=sensor64[at_lid],
        cam_path=[_basename(p) for p in d.filename[cam.ravel()].tolist()], cam2img=d.intrinsic[cam],
        cam2ego=sensor[at_cam], cam_token=d.token[cam], cam_timestamp_s=d.timestamp_us[cam] / 1e6,
        lidar2cam=transforms.sensor_from_lidar_f32(c.cam_s2l_r[samples], c.cam_s2l_t[samples], f32=f32),
        sweep_offsets=sweep_offsets, sweep_timestamp_s=d.timestamp_us[sweep_row] / 1e6,
        sweep_ego2global=ego[at_sweep],
        sweep_path=d.filename[sweep_row].tolist() if corrected
        else [os.path.join(prefix, p) for p in d.filename[sweep_row].tolist()],
        sweep_lidar2ego=sensor[at_sweep],
        sweep_lidar2sensor=transforms.sensor_from_lidar_f32(c.sweep_s2l_r[sweeps], c.sweep_s2l_t[sweeps], f32=f32),
        sweep_token=d.token[sweep_row],
        ann_offsets=ann_offsets, ann_label=label_of(categories), ann_name=mapped_names(categories),
        ann_box=c.gt_boxes[anns], ann_num_lidar_pts=inp.ann_num_lidar_pts[rows],
        ann_num_radar_pts=inp.ann_num_radar_pts[rows],
        ann_valid=(inp.ann_num_lidar_pts[rows] + inp.ann_num_radar_pts[rows]) > 0, ann_velocity=c.gt_velocity[anns],
        semantic_mask_path=None if mask_files is None
        else [_basename(os.path.join(prefix, f)) for f in mask_files[samples].tolist()],
        ci_offsets=None, ci_label=None, ci_bbox=None, ci_bbox_3d=None, ci_velocity=None, ci_center_2d=None,
        ci_depth=None, ci_attr_label=None)
    ci = c.cam_instances
    if ci is not None:
        n_cam = len(cameras)
        segments = (samples[:, None] * n_cam + np.arange(n_cam)).ravel()
        picked, out.ci_offsets = gather_segments(offsets(ci.sample * n_cam + ci.camera, n * n_cam), segments)
        out.ci_label, out.ci_bbox, out.ci_bbox_3d = ci.label[picked], ci.bbox[picked], ci.bbox_3d[picked]
        out.ci_velocity, out.ci_center_2d = ci.velocity[picked], ci.center_2d[picked]
        out.ci_depth, out.ci_attr_label = ci.depth[picked], ci.attr_label[picked]
    return out
