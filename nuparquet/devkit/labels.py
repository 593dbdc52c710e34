"""nuScenes-lidarseg and Panoptic nuScenes labels for the devkit's label printers: from the converted `lidar_points/`
(`convert --sensors lidar` of a dataset with label files) when it holds every labelled frame, else from the label
files under the dataroot, as the devkit reads them. Both give the same labels; the Parquet is read in one query.
"""

from __future__ import annotations

import os.path as osp

import numpy as np
import polars as pl

from nuparquet.devkit.utils.data_io import load_bin_file, panoptic_to_lidarseg

LABEL_COLUMN = {"lidarseg": "lidarseg_label", "panoptic": "panoptic_label"}
STUFF_START_CLASS_ID = 24  # Panoptic nuScenes: classes from here on are "stuff" (no instances)


def frame_labels(nusc, gt_from: str, sample_data_tokens: list[str]) -> list[np.ndarray]:
    """The `gt_from` labels of each frame (lidarseg: uint8 class; panoptic: class * 1000 + instance), in order."""
    converted = _converted_labels(nusc, gt_from, sample_data_tokens)
    if converted is not None:
        return converted
    table = getattr(nusc, gt_from)
    return [load_bin_file(osp.join(nusc.dataroot, nusc.get(gt_from, token)["filename"]), type=gt_from)
            for token in sample_data_tokens] if table is not None else []


def _converted_labels(nusc, gt_from: str, tokens: list[str]) -> list[np.ndarray] | None:
    """The labels from lidar_points/, or None when it is absent or lacks a frame's labels."""
    dataset = nusc._dataset
    column = LABEL_COLUMN[gt_from]
    if "lidar_points" not in dataset.datasets or not tokens:
        return None
    rows = (dataset.scan("lidar_points")
            .filter(pl.col("sample_data_token").cast(pl.String).is_in(pl.Series(tokens, dtype=pl.String).implode()))
            .select(pl.col("sample_data_token").cast(pl.String), column)
            .collect())
    if rows[column].null_count():
        return None
    by_frame = {key[0]: frame[column].to_numpy() for key, frame in rows.group_by("sample_data_token",
                                                                                    maintain_order=True)}
    if set(by_frame) != set(tokens):
        return None
    return [by_frame[token].astype(np.uint8 if gt_from == "lidarseg" else np.uint16) for token in tokens]


def class_counts(labels: np.ndarray, gt_from: str) -> np.ndarray:
    """(C,) points per lidarseg class index of one frame's labels (panoptic labels: their class)."""
    if gt_from == "panoptic":
        labels = panoptic_to_lidarseg(labels)
    return np.bincount(labels)


def panoptic_instance_stats(frames: list[tuple[str, np.ndarray]], cat_idx2name: dict[int, str],
                            get_hist: bool = False) -> dict:
    """The devkit's `get_panoptic_instances_stats` over `frames` ([(scene token, panoptic labels)] in table order):
    instances per frame, and per thing class the instances, the frames each spans and the points each holds.

    The same numpy steps as the devkit's, so the printed means and deviations are its own."""
    scene_rows: dict[str, list[np.ndarray]] = {}
    for frame_id, (scene, labels) in enumerate(frames):
        values, counts = np.unique(labels, return_counts=True)
        inst_count = np.array([values, counts]).T
        rows = np.concatenate([inst_count[:, 0:1] // 1000, inst_count[:, 0:1] % 1000, inst_count[:, 1:]],
                              axis=1).astype(np.int32)
        rows = np.concatenate([np.full((rows.shape[0], 1), frame_id, dtype=np.int32), rows], axis=1)
        scene_rows.setdefault(scene, []).append(rows)
    assert len(scene_rows) > 0, "Empty input data !"
    data = np.empty((0, 5), dtype=np.int32)
    for scene_id, parts in enumerate(scene_rows.values()):
        scene_data = np.empty((0, 4), dtype=np.int32)
        for part in parts:
            scene_data = np.append(scene_data, part, axis=0)
        scene_data = np.concatenate([np.full((scene_data.shape[0], 1), scene_id, dtype=np.int32), scene_data], axis=1)
        data = np.concatenate([data, scene_data], axis=0)

    data_thing = data[np.logical_and(data[:, 2] > 0, data[:, 2] < STUFF_START_CLASS_ID)]
    inst_num_each_frame = np.array(np.unique(1000 * data_thing[:, 0] + data_thing[:, 1], return_counts=True))[1]
    per_frame = {"per_frame_num_instances": (np.mean(inst_num_each_frame), np.std(inst_num_each_frame))}
    if get_hist:
        per_frame["per_frame_num_instances_hist"] = np.array(np.unique(inst_num_each_frame, return_counts=True)).T

    per_category: dict[str, dict] = {}
    unique_cat_ids = np.array(np.unique(data_thing[:, 2]))
    unique_inst_ids = 1000 * data_thing[:, 0] + data_thing[:, 3]
    for cat_id in unique_cat_ids:
        mask = data_thing[:, 2] == cat_id
        frame_count = np.array(np.unique(unique_inst_ids[mask], return_counts=True))[1]
        num_pts = data_thing[mask, 4]
        per_category[cat_idx2name[cat_id]] = {
            "num_instances": len(frame_count),
            "num_frames_per_instance": (np.mean(frame_count), np.std(frame_count)),
            "num_points_per_instance": (np.mean(num_pts), np.std(num_pts)),
        }
        if get_hist:
            per_category[cat_idx2name[cat_id]].update({"num_frames_per_instance_count": frame_count,
                                                       "num_points_per_instance_count": num_pts})
    total_instances = np.sum([v["num_instances"] for v in per_category.values()])
    for i, name in cat_idx2name.items():
        if 0 < i < STUFF_START_CLASS_ID and i not in unique_cat_ids:
            per_category[name] = {"num_instances": 0, "num_frames_per_instance": (0, 0),
                                  "num_points_per_instance": (0, 0),
                                  "num_frames_per_instance_count": np.array([], dtype=np.int32),
                                  "num_points_per_instance_count": np.array([], dtype=np.int32)}
    return {"num_instances": total_instances, "num_sample_annotations": np.sum(inst_num_each_frame),
            "per_frame_panoptic_stats": per_frame, "per_category_panoptic_stats": per_category}
