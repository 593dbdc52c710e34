"""The info dicts themselves, v1 (`create_nuscenes_infos`) and v2 (`update_nuscenes_infos`), with the
converter's key order and value types, from `Computed` arrays. The numbers are all computed already; this
only slices arrays per sample and converts them to the Python/numpy objects the pickles hold."""

from __future__ import annotations

import os
from pathlib import PurePosixPath

import numpy as np

from nuparquet.index import transforms
from nuparquet.index.compute import Computed, offsets
from nuparquet.index.labels import CLASSES, label_of, mapped_names

NUM_PTS_FEATS = 5  # nuScenes lidar: x, y, z, intensity, ring index


def _reading(c: Computed, row: int, kind: str, prefix: str, r: np.ndarray, t: np.ndarray) -> dict:
    d = c.inputs.data
    return {
        "data_path": os.path.join(prefix, d.filename[row]), "type": kind, "sample_data_token": d.token[row],
        "sensor2ego_translation": d.sensor_t[row].tolist(), "sensor2ego_rotation": d.sensor_q[row].tolist(),
        "ego2global_translation": d.ego_t[row].tolist(), "ego2global_rotation": d.ego_q[row].tolist(),
        "timestamp": int(d.timestamp_us[row]), "sensor2lidar_rotation": r, "sensor2lidar_translation": t,
    }


def v1_infos(c: Computed, samples: np.ndarray, cameras: tuple[str, ...], prefix: str, test: bool) -> list[dict]:
    """One v1 info dict per sample row in `samples`."""
    inp, d = c.inputs, c.inputs.data
    sweep_offsets = offsets(c.sweep_owner, len(inp.sample_token))
    names = mapped_names(inp.ann_category[c.ann_order])
    infos = []
    for s in samples:
        lid = c.lidar_row[s]
        sweeps = [_reading(c, c.sweep_row[w], "lidar", prefix, c.sweep_s2l_r[w], c.sweep_s2l_t[w])
                  for w in range(sweep_offsets[s], sweep_offsets[s + 1])]
        cams = {}
        for k, cam in enumerate(cameras):
            cams[cam] = _reading(c, c.cam_row[s, k], cam, prefix, c.cam_s2l_r[s, k], c.cam_s2l_t[s, k])
            cams[cam]["cam_intrinsic"] = d.intrinsic[c.cam_row[s, k]].copy()
        info = {
            "lidar_path": os.path.join(prefix, d.filename[lid]), "num_features": NUM_PTS_FEATS,
            "token": inp.sample_token[s], "sweeps": sweeps, "cams": cams,
            "lidar2ego_translation": d.sensor_t[lid].tolist(), "lidar2ego_rotation": d.sensor_q[lid].tolist(),
            "ego2global_translation": d.ego_t[lid].tolist(), "ego2global_rotation": d.ego_q[lid].tolist(),
            "timestamp": int(inp.sample_timestamp_us[s]),
        }
        if not test:
            a = slice(c.ann_offsets[s], c.ann_offsets[s + 1])
            rows = c.ann_order[a]
            info["gt_boxes"] = c.gt_boxes[a].reshape(-1, 7)
            info["gt_names"] = np.array(names[a].tolist())
            info["gt_velocity"] = c.gt_velocity[a].reshape(-1, 2)
            info["num_lidar_pts"] = np.array(inp.ann_num_lidar_pts[rows].tolist())
            info["num_radar_pts"] = np.array(inp.ann_num_radar_pts[rows].tolist())
            info["valid_flag"] = (inp.ann_num_lidar_pts[rows] + inp.ann_num_radar_pts[rows]) > 0
        infos.append(info)
    return infos


def _copy(matrix: list) -> list:
    """A fresh nested list per entry, so that no two entries share a matrix object."""
    return [row[:] for row in matrix]


def v2_infos(c: Computed, samples: np.ndarray, cameras: tuple[str, ...], prefix: str, *,
             corrected: bool = False) -> tuple[list[dict], set[str], set[str]]:
    """(data_list, unmapped classes of the last sample (what the converter's metainfo keeps), unmapped classes
    of every sample). `corrected`: float64 matrices, sweep paths relative like keyframe ones, num_pts_feats."""
    inp, d = c.inputs, c.inputs.data
    f32 = not corrected
    n = len(inp.sample_token)
    sweep_offsets = offsets(c.sweep_owner, n)
    sweep_l2s = transforms.sensor_from_lidar_f32(c.sweep_s2l_r, c.sweep_s2l_t, f32=f32)
    cam_l2c = transforms.sensor_from_lidar_f32(c.cam_s2l_r, c.cam_s2l_t, f32=f32)
    # every 4x4 the entries need, computed once for all readings (not one small matrix at a time)
    used = np.unique(np.concatenate([c.lidar_row[samples], c.cam_row[samples].ravel(), c.sweep_row]))
    ego_m = dict(zip(used.tolist(), transforms.pose_matrix_f32(d.ego_q[used], d.ego_t[used], f32=f32).tolist()))
    sensor_m = dict(zip(used.tolist(), transforms.pose_matrix_f32(d.sensor_q[used], d.sensor_t[used], f32=f32).tolist()))
    names = mapped_names(inp.ann_category[c.ann_order])
    labels = label_of(inp.ann_category[c.ann_order]).tolist()
    boxes, velocity = c.gt_boxes.tolist(), c.gt_velocity.tolist()
    ci = c.cam_instances
    ci_offsets = offsets(ci.sample * len(cameras) + ci.camera, n * len(cameras)) if ci is not None else None
    if ci is not None:
        ci_bbox = [[np.float64(v) for v in row] for row in ci.bbox.tolist()]
        ci_box3d, ci_vel = ci.bbox_3d.tolist(), ci.velocity.tolist()
        ci_c2d, ci_depth = ci.center_2d.tolist(), ci.depth.tolist()
        ci_label, ci_attr = ci.label.tolist(), ci.attr_label.tolist()
    data_list, last_ignored, all_ignored = [], set(), set()
    cam_rows = c.cam_row.tolist()
    for i, s in enumerate(samples.tolist()):
        lid = int(c.lidar_row[s])
        entry = {"sample_idx": i, "token": inp.sample_token[s], "timestamp": int(inp.sample_timestamp_us[s]) / 1e6,
                 "ego2global": _copy(ego_m[lid])}
        images = {}
        for k, cam in enumerate(cameras):
            row = cam_rows[s][k]
            images[cam] = {"img_path": PurePosixPath(d.filename[row]).name, "cam2img": d.intrinsic[row].tolist(),
                           "cam2ego": _copy(sensor_m[row]),
                           "sample_data_token": d.token[row], "timestamp": int(d.timestamp_us[row]) / 1e6,
                           "lidar2cam": cam_l2c[s, k].tolist()}
        entry["images"] = images
        entry["lidar_points"] = {"num_pts_feats": NUM_PTS_FEATS, "lidar_path": PurePosixPath(d.filename[lid]).name,
                                 "lidar2ego": _copy(sensor_m[lid])}
        sweeps = []
        for w in range(sweep_offsets[s], sweep_offsets[s + 1]):
            row = int(c.sweep_row[w])
            path = d.filename[row] if corrected else os.path.join(prefix, d.filename[row])
            sweeps.append({"timestamp": int(d.timestamp_us[row]) / 1e6, "ego2global": _copy(ego_m[row]),
                           "lidar_points": {"num_pts_feats": NUM_PTS_FEATS if corrected else None, "lidar_path": path,
                                            "lidar2ego": _copy(sensor_m[row]),
                                            "lidar2sensor": sweep_l2s[w].tolist()},
                           "sample_data_token": d.token[row]})
        if sweeps:  # the converter drops empty lists (clear_data_info_unused_keys)
            entry["lidar_sweeps"] = sweeps
        instances, ignored = [], set()
        for a in range(c.ann_offsets[s], c.ann_offsets[s + 1]):
            row = c.ann_order[a]
            if labels[a] < 0:
                ignored.add(names[a])
            instances.append({"bbox_label": labels[a], "bbox_3d": boxes[a],
                              "bbox_3d_isvalid": np.bool_(inp.ann_num_lidar_pts[row] + inp.ann_num_radar_pts[row] > 0),
                              "bbox_label_3d": labels[a], "num_lidar_pts": np.int64(inp.ann_num_lidar_pts[row]),
                              "num_radar_pts": np.int64(inp.ann_num_radar_pts[row]), "velocity": velocity[a]})
        entry["instances"] = instances
        last_ignored, all_ignored = ignored, all_ignored | ignored
        if ci is not None:
            cam_instances = {}
            for k, cam in enumerate(cameras):
                lo, hi = ci_offsets[s * len(cameras) + k], ci_offsets[s * len(cameras) + k + 1]
                cam_instances[cam] = [
                    {"bbox_label": ci_label[j], "bbox_label_3d": ci_label[j], "bbox": ci_bbox[j],
                     "bbox_3d_isvalid": True, "bbox_3d": ci_box3d[j][:6] + [np.float64(ci_box3d[j][6])],
                     "velocity": ci_vel[j], "center_2d": ci_c2d[j], "depth": ci_depth[j], "attr_label": ci_attr[j]}
                    for j in range(lo, hi)]
            entry["cam_instances"] = cam_instances
        data_list.append(entry)
    return data_list, last_ignored, all_ignored


def v2_metainfo(version: str, ignored: set[str]) -> dict:
    categories = {name: i for i, name in enumerate(CLASSES)}
    categories |= dict.fromkeys(ignored, -1)
    return {"categories": categories, "dataset": "nuscenes", "version": version, "info_version": "1.1"}
