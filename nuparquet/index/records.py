"""The info dicts themselves, v1 (`create_nuscenes_infos`) and v2 (`update_nuscenes_infos`), with the
converter's key order and value types, from `Computed` arrays. The numbers are all computed already; this
only slices arrays per sample and converts them to the Python/numpy objects the pickles hold."""

from __future__ import annotations

import os

import numpy as np

from nuparquet.index.compute import Computed, offsets
from nuparquet.index.labels import CLASSES, mapped_names
from nuparquet.index.v2_arrays import V2Arrays

NUM_PTS_FEATS = 5  # nuScenes lidar: x, y, z, intensity, ring index


def _reading(c: Computed, row: int, kind: str, prefix: str, r: np.ndarray, t: np.ndarray) -> dict:
    d = c.inputs.data
    return {
        "data_path": os.path.join(prefix, d.filename[row]), "type": kind, "sample_data_token": d.token[row],
        "sensor2ego_translation": d.sensor_t[row].tolist(), "sensor2ego_rotation": d.sensor_q[row].tolist(),
        "ego2global_translation": d.ego_t[row].tolist(), "ego2global_rotation": d.ego_q[row].tolist(),
        "timestamp": int(d.timestamp_us[row]), "sensor2lidar_rotation": r, "sensor2lidar_translation": t,
    }


def v1_infos(c: Computed, samples: np.ndarray, cameras: tuple[str, ...], prefix: str, test: bool,
             mask_files: np.ndarray | None = None) -> list[dict]:
    """One v1 info dict per sample row in `samples`. `mask_files` (S,): each sample's lidarseg label file
    (`lidarseg.semantic_mask_files`), None without lidarseg."""
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
            if mask_files is not None:
                info["pts_semantic_mask_path"] = os.path.join(prefix, mask_files[s])
        infos.append(info)
    return infos


def _lists(matrices: np.ndarray) -> list:
    """Nested lists of Python floats; float32 widened first (the same values, ~15% faster than tolist of
    float32, which goes through numpy scalars)."""
    return matrices.astype(np.float64).tolist()


def _chunks(items: list, size: int) -> list:
    return [items[i:i + size] for i in range(0, len(items), size)]


def v2_ignored(v: V2Arrays) -> tuple[set[str], set[str]]:
    """(unmapped classes of the last sample: what the converter's metainfo keeps, as `ignore_class_name` is
    reset per sample; unmapped classes of every sample: the corrected form)."""
    unmapped = v.ann_label < 0
    last = set(v.ann_name[v.ann_offsets[-2]:][unmapped[v.ann_offsets[-2]:]].tolist()) if len(v.token) else set()
    return last, set(v.ann_name[unmapped].tolist())


def v2_infos(v: V2Arrays, *, corrected: bool = False, first_index: int = 0) -> list[dict]:
    """The data_list entries of the samples of `v` (`sample_idx` counted from `first_index`). `corrected`
    (with `v` built corrected): num_pts_feats of sweeps set.

    Every array becomes Python objects in one `tolist` call (or one iteration, for the numpy scalars the
    reference holds); the loop below only assembles dicts in the converter's key order.
    """
    cameras = v.cameras
    n_cam = len(cameras)
    e2g, l2e = _lists(v.ego2global), _lists(v.lidar2ego)
    cam2img, cam2ego, lidar2cam = v.cam2img.tolist(), _lists(v.cam2ego), _lists(v.lidar2cam)
    cam_token, cam_time = v.cam_token.tolist(), v.cam_timestamp_s.tolist()
    images = [
        {cam: {"img_path": v.cam_path[s * n_cam + k], "cam2img": cam2img[s][k], "cam2ego": cam2ego[s][k],
               "sample_data_token": cam_token[s][k], "timestamp": cam_time[s][k], "lidar2cam": lidar2cam[s][k]}
         for k, cam in enumerate(cameras)}
        for s in range(len(v.token))]
    sweep_pts = NUM_PTS_FEATS if corrected else None
    sweeps = [{"timestamp": t, "ego2global": e, "lidar_points": {"num_pts_feats": sweep_pts, "lidar_path": p,
                                                                  "lidar2ego": le, "lidar2sensor": ls},
               "sample_data_token": tok}
              for t, e, p, le, ls, tok in zip(v.sweep_timestamp_s.tolist(), _lists(v.sweep_ego2global), v.sweep_path,
                                             _lists(v.sweep_lidar2ego), _lists(v.sweep_lidar2sensor),
                                             v.sweep_token.tolist())]
    labels = v.ann_label.tolist()
    instances = [{"bbox_label": label, "bbox_3d": box, "bbox_3d_isvalid": valid, "bbox_label_3d": label,
                  "num_lidar_pts": lidar, "num_radar_pts": radar, "velocity": vel}
                 for label, box, valid, lidar, radar, vel in zip(labels, v.ann_box.tolist(), list(v.ann_valid),
                                                                list(v.ann_num_lidar_pts), list(v.ann_num_radar_pts),
                                                                v.ann_velocity.tolist())]
    cam_instances = None
    if v.ci_offsets is not None:
        yaw = list(v.ci_bbox_3d[:, 6])  # np.float64 in the reference (the rest are Python floats)
        ci_label = v.ci_label.tolist()
        cam_instances = [
            {"bbox_label": label, "bbox_label_3d": label, "bbox": bbox, "bbox_3d_isvalid": True,
             "bbox_3d": box[:6] + [y], "velocity": vel, "center_2d": c2d, "depth": depth, "attr_label": attr}
            for label, bbox, box, y, vel, c2d, depth, attr in zip(
                ci_label, _chunks(list(v.ci_bbox.ravel()), 4), v.ci_bbox_3d.tolist(), yaw, v.ci_velocity.tolist(),
                v.ci_center_2d.tolist(), v.ci_depth.tolist(), v.ci_attr_label.tolist())]
    sweep_offsets, ann_offsets = v.sweep_offsets.tolist(), v.ann_offsets.tolist()
    ci_offsets = v.ci_offsets.tolist() if v.ci_offsets is not None else None
    tokens, times, lidar_paths = v.token.tolist(), v.timestamp_s.tolist(), v.lidar_path
    data_list = []
    for i in range(len(v.token)):
        entry = {"sample_idx": first_index + i, "token": tokens[i], "timestamp": times[i], "ego2global": e2g[i],
                 "images": images[i],
                 "lidar_points": {"num_pts_feats": NUM_PTS_FEATS, "lidar_path": lidar_paths[i], "lidar2ego": l2e[i]}}
        lo, hi = sweep_offsets[i], sweep_offsets[i + 1]
        if hi > lo:  # the converter drops empty lists (clear_data_info_unused_keys)
            entry["lidar_sweeps"] = sweeps[lo:hi]
        lo, hi = ann_offsets[i], ann_offsets[i + 1]
        entry["instances"] = instances[lo:hi]
        if v.semantic_mask_path is not None:  # the template's key, after instances (cam_instances is added later)
            entry["pts_semantic_mask_path"] = v.semantic_mask_path[i]
        if cam_instances is not None:
            entry["cam_instances"] = {cam: cam_instances[ci_offsets[i * n_cam + k]:ci_offsets[i * n_cam + k + 1]]
                                      for k, cam in enumerate(cameras)}
        data_list.append(entry)
    return data_list


def v2_metainfo(version: str, ignored: set[str]) -> dict:
    categories = {name: i for i, name in enumerate(CLASSES)}
    categories |= dict.fromkeys(ignored, -1)
    return {"categories": categories, "dataset": "nuscenes", "version": version, "info_version": "1.1"}
