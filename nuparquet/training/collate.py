"""`collate`: a list of `Samples` items as one batch of numpy arrays (a DataLoader's `collate_fn`; torch users turn
the arrays into tensors with `torch.from_numpy` where they need them)."""

from __future__ import annotations

import numpy as np

STACKED = ("img", "cam2img", "lidar2cam", "cam2lidar", "lidar2img", "can_bus", "gt_masks_bev", "queue_index")
LISTED = ("gt_bboxes_3d", "gt_labels_3d", "num_lidar_pts")  # a different count per item: lists of B arrays
POINTS = ("points", "radar_points")  # a different count per item: concatenated (or padded) with lengths
NUMBERS = {"timestamp_us": np.int64, "lidar_sweeps": np.int64, "prev_bev_exists": bool}


def collate(items: list[dict], *, pad_points: bool = False) -> dict:
    """The batch of `items` (B of them), key by key:

    - `points`, `radar_points`: (sum P, F) float32, the items' points concatenated, with `points_lengths` /
      `radar_points_lengths` (B,) int64; with `pad_points`, (B, max P, F) zero-padded instead (same lengths)
    - `img` (B, C, H, W, 3) uint8, `cam2img` / `lidar2cam` / `cam2lidar` / `lidar2img` (B, C, 4, 4), `can_bus`
      (B, 18), `gt_masks_bev` (B, K, H, W), `queue_index` (B, Q): stacked (a list when the shapes differ)
    - `gt_bboxes_3d`, `gt_labels_3d`, `num_lidar_pts`: lists of the items' arrays
    - `timestamp_us`, `lidar_sweeps`: (B,) int64; `prev_bev_exists`: (B,) bool
    - `queue`: a list of Q - 1 batches, the items' previous frames collated position by position (oldest first)
    - every other key (tokens): a list
    """
    if not items:
        raise ValueError("collate needs at least one item")
    batch: dict = {}
    for key in items[0]:
        values = [item[key] for item in items]
        if key in POINTS:
            batch[key], batch[f"{key}_lengths"] = _points(values, pad_points)
        elif key in STACKED:
            same = all(isinstance(v, np.ndarray) for v in values) and len({v.shape for v in values}) == 1
            batch[key] = np.stack(values) if same else values
        elif key in NUMBERS:
            batch[key] = np.array(values, dtype=NUMBERS[key])
        elif key == "queue":
            batch[key] = [collate([frames[k] for frames in values], pad_points=pad_points)
                          for k in range(len(values[0]))]
        else:
            batch[key] = values  # LISTED and the tokens
    return batch


def _points(values: list[np.ndarray], pad: bool) -> tuple[np.ndarray, np.ndarray]:
    lengths = np.array([len(v) for v in values], dtype=np.int64)
    if not pad:
        return np.concatenate(values).astype(np.float32, copy=False), lengths
    padded = np.zeros((len(values), int(lengths.max(initial=0)), values[0].shape[1]), np.float32)
    for b, v in enumerate(values):
        padded[b, :len(v)] = v
    return padded, lengths
