"""The BEVFormer/UniAD v1 variant (their `tools/data_converter/nuscenes_converter.py`): v1 infos plus `prev`,
`next`, `frame_idx` (position in the scene), `scene_token`, the 18-value `can_bus` vector of the sample and
boxes as [x, y, z, w, l, h, -yaw - pi/2]. The `can_bus` vectors come from the `sample_can_bus` dataset (one row
per sample_token, column `can_bus`: list<float64>[18]), written by the CAN bus conversion."""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.columns import to_numpy
from nuparquet.dataset import Dataset
from nuparquet.errors import InputError
from nuparquet.index.compute import Computed
from nuparquet.index.legacy import DROPPED_V1_KEYS, boxes_v0

CAN_BUS_DATASET = "sample_can_bus"
CAN_BUS_WIDTH = 18


def can_bus_vectors(ds: Dataset, sample_tokens: np.ndarray) -> np.ndarray:
    """(S, 18) the can_bus vector of each sample; zeros for a sample without CAN bus data (BEVFormer's
    converter does the same for scenes the CAN bus expansion lacks)."""
    if CAN_BUS_DATASET not in ds.datasets:
        raise InputError(f"{ds.root} has no {CAN_BUS_DATASET} dataset, which --format bevformer needs (its can_bus "
                         "vectors): convert the dataset again with its CAN bus expansion (DATAROOT/can_bus)")
    table = ds.scan(CAN_BUS_DATASET).select("sample_token", "can_bus").collect()
    joined = pl.DataFrame({"sample_token": sample_tokens}).join(table, on="sample_token", how="left",
                                                               maintain_order="left")
    vectors = to_numpy(joined["can_bus"], (CAN_BUS_WIDTH,), writable=True)
    vectors[np.isnan(vectors).all(axis=1)] = 0.0
    return vectors


def frame_indices(sample_scene: np.ndarray, sample_next: np.ndarray) -> np.ndarray:
    """(S,) BEVFormer's frame_idx: counts samples in table order, back to 0 after a sample with no next."""
    ends = np.flatnonzero(sample_next == "")
    starts = np.concatenate([[0], ends[:-1] + 1]) if len(ends) else np.array([0])
    idx = np.arange(len(sample_next))
    start_of = starts[np.searchsorted(starts, idx, side="right") - 1]
    return idx - start_of


def bevformer_infos(c: Computed, v1: list[dict], samples: np.ndarray, sample_prev: np.ndarray,
                    sample_next: np.ndarray, can_bus: np.ndarray) -> list[dict]:
    """Add BEVFormer's keys to v1 infos (of `samples`, in order) and switch their boxes to its layout."""
    inp = c.inputs
    frame_idx = frame_indices(inp.sample_scene, sample_next)
    out = []
    for info, s in zip(v1, samples):
        head = {"lidar_path": info["lidar_path"], "token": info["token"], "prev": sample_prev[s],
                "next": sample_next[s], "can_bus": can_bus[s].copy(), "frame_idx": int(frame_idx[s]),
                "sweeps": info["sweeps"], "cams": info["cams"], "scene_token": inp.sample_scene[s]}
        # its converter is mmdetection3d 0.17's with these keys added: no num_features, no lidarseg path
        rest = {k: v for k, v in info.items() if k not in head and k not in DROPPED_V1_KEYS}
        if "gt_boxes" in rest:
            rest["gt_boxes"] = boxes_v0(rest["gt_boxes"])  # x, y, z, w, l, h, -yaw - pi/2
        out.append(head | rest)
    return out
