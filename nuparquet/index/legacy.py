"""`--format mmdet3d-legacy`: what mmdetection3d 0.17.x (`tools/data_converter/nuscenes_converter.py`, the same
file in 0.17.0 to 0.17.3) writes for nuScenes, the files BEVDet, BEVFusion, PETR, StreamPETR, Fast-BEV and FCOS3D
still read.

- `nuscenes_infos_<split>.pkl`: `create_nuscenes_infos`: v1.4.0's v1 infos without `num_features` and without
  `pts_semantic_mask_path` (0.17 has neither), with `gt_boxes` as (x, y, z, w, l, h, -yaw - pi/2) ("SECOND
  format"). Every other number is computed by the same lines as in v1.4.0.
- `nuscenes_infos_<split>_mono3d.coco.json`: `export_2d_annotation(..., mono3d=True)` of that pickle: one image
  per (sample, camera) and one annotation per box record of `get_2d_boxes`, which are v1.4.0's camera instances
  (`cam_instances.camera_instances(legacy=True)`: there the centre and depth are float64 numpy), numbered from 0
  in (sample, camera, annotation) order, written as `mmcv.dump` writes JSON (`json.dump`, default separators).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.atomic import atomic_file
from nuparquet.dataset import Dataset
from nuparquet.index.cam_instances import CamInstances
from nuparquet.index.compute import Computed, offsets
from nuparquet.index.labels import ATTRIBUTES, CLASSES
from nuparquet.index.v2_arrays import gather_segments

DROPPED_V1_KEYS = ("num_features", "pts_semantic_mask_path")  # v1.4.0 v1 keys that 0.17 does not write
COCO_CHUNK = 20_000  # annotations encoded at a time: a trainval split has ~1M


def boxes_v0(gt_boxes: np.ndarray) -> np.ndarray:
    """(N, 7) 0.17's `np.concatenate([locs, dims, -rots - np.pi / 2], axis=1)` (dims as w, l, h) from v1.4.0's
    (N, 7) [x, y, z, l, w, h, yaw] (the same locs, dims and rots: the swap is exact, the arithmetic the same)."""
    b = np.asarray(gt_boxes).reshape(-1, 7)
    return np.concatenate([b[:, :3], b[:, [4, 3, 5]], -b[:, 6:7] - np.pi / 2], axis=1)


def legacy_infos(v1: list[dict]) -> list[dict]:
    """0.17's infos from v1.4.0's v1 infos (`records.v1_infos`): the same keys in the same order, less two."""
    out = []
    for info in v1:
        legacy = {k: v for k, v in info.items() if k not in DROPPED_V1_KEYS}
        if "gt_boxes" in legacy:
            legacy["gt_boxes"] = boxes_v0(legacy["gt_boxes"])
        out.append(legacy)
    return out


def camera_image_sizes(ds: Dataset, tokens: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((N,) width, (N,) height) of camera readings `tokens`, from sample_data: the converter reads them off
    the image (`mmcv.imread(path).shape`); nuScenes' table sizes are the files' (checked by the tests)."""
    table = (ds.scan("tables/sample_data").filter(pl.col("token").is_in(pl.Series(tokens).implode()))
             .select("token", "width", "height").collect())
    joined = pl.DataFrame({"token": tokens}, schema={"token": pl.String}).join(table, on="token", how="left",
                                                                            maintain_order="left")
    return joined["width"].to_numpy(), joined["height"].to_numpy()


def _images(c: Computed, samples: np.ndarray, prefix: str, width: np.ndarray, height: np.ndarray) -> list[dict]:
    """The `images` of one split: per sample, per camera (info order), as `export_2d_annotation` builds them
    from the info. `ego2global_*` is the info's, i.e. the lidar keyframe's ego pose, not the camera's."""
    d = c.inputs.data
    images = []
    for s in samples:
        lid = c.lidar_row[s]
        ego_q, ego_t = d.ego_q[lid].tolist(), d.ego_t[lid].tolist()
        token = c.inputs.sample_token[s]
        for k, row in enumerate(c.cam_row[s]):
            # cam_info['data_path'] is osp.join(dataroot, filename): split on 'data/nuscenes/' as the converter
            images.append({
                "file_name": os.path.join(prefix, d.filename[row]).split("data/nuscenes/")[-1], "id": d.token[row],
                "token": token, "cam2ego_rotation": d.sensor_q[row].tolist(),
                "cam2ego_translation": d.sensor_t[row].tolist(), "ego2global_rotation": ego_q,
                "ego2global_translation": ego_t, "cam_intrinsic": d.intrinsic[row].tolist(),
                "width": int(width[s, k]), "height": int(height[s, k])})
    return images


def _annotations(c: Computed, ci: CamInstances, picked: np.ndarray, first_id: int) -> list[dict]:
    """COCO annotations of records `picked` of `ci` (in output order), ids from `first_id`: `generate_record`'s
    keys, the mono3d keys of `get_2d_boxes`, then `segmentation` and `id` added by `export_2d_annotation`."""
    d = c.inputs.data
    cam_row = c.cam_row[ci.sample[picked], ci.camera[picked]]
    x1, y1, x2, y2 = ci.bbox[picked].T
    area = ((y2 - y1) * (x2 - x1)).tolist()
    bbox = np.stack([x1, y1, x2 - x1, y2 - y1], axis=1).tolist()
    labels = ci.label[picked].tolist()
    attr = ci.attr_label[picked].tolist()
    center2d = np.column_stack([ci.center_2d[picked], ci.depth[picked]]).tolist()
    return [{"file_name": file_name, "image_id": token, "area": a, "category_name": CLASSES[label],
             "category_id": label, "bbox": b, "iscrowd": 0, "bbox_cam3d": box, "velo_cam3d": velo,
             "center2d": c2d, "attribute_name": ATTRIBUTES[at], "attribute_id": at, "segmentation": [],
             "id": first_id + i}
            for i, (file_name, token, a, label, b, box, velo, c2d, at) in enumerate(zip(
                d.filename[cam_row].tolist(), d.token[cam_row].tolist(), area, labels, bbox,
                ci.bbox_3d[picked].tolist(), ci.velocity[picked].tolist(), center2d, attr))]


def _list_body(items: list) -> str:
    """`json.dumps(items)` without its brackets (items joined by ', ', as inside any list json writes)."""
    return json.dumps(items)[1:-1]


def write_mono3d_coco(path: Path, c: Computed, ci: CamInstances, samples: np.ndarray, prefix: str,
                      width: np.ndarray, height: np.ndarray) -> int:
    """Write the split's `*_mono3d.coco.json` (atomically) as `mmcv.dump` of
    `{annotations, images, categories}` writes it, annotations encoded COCO_CHUNK at a time. `width`,
    `height`: (S, C) of every sample's cameras. Returns the number of annotations."""
    n_cam = c.cam_row.shape[1]
    segments = (samples[:, None] * n_cam + np.arange(n_cam)).ravel()
    picked, _ = gather_segments(offsets(ci.sample * n_cam + ci.camera, len(c.inputs.sample_token) * n_cam),
                                segments)
    categories = [{"id": i, "name": name} for i, name in enumerate(CLASSES)]
    with atomic_file(path) as tmp:
        with open(tmp, "w") as f:
            f.write('{"annotations": [')
            for lo in range(0, len(picked), COCO_CHUNK):
                if lo:
                    f.write(", ")
                f.write(_list_body(_annotations(c, ci, picked[lo:lo + COCO_CHUNK], lo)))
            f.write('], "images": [')
            f.write(_list_body(_images(c, samples, prefix, width, height)))
            f.write('], "categories": ')
            f.write(json.dumps(categories))
            f.write("}")
    return len(picked)
