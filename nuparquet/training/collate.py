"""`collate`: a list of `Samples` items as one batch of numpy arrays (a DataLoader's `collate_fn`; torch users turn
the arrays into tensors with `torch.from_numpy` where they need them)."""

from __future__ import annotations

import numpy as np

STACKED = ("img", "cam2img", "lidar2cam", "lidar2img")  # same shape in every item of a rig: (B, C, ...)
LISTED = ("gt_bboxes_3d", "gt_labels_3d", "num_lidar_pts")  # a different count per item: lists of B arrays


def collate(items: list[dict], *, pad_points: bool = False) -> dict:
    """The batch of `items` (B of them), key by key:

    - `points`: (sum P, 5) float32, the items' points concatenated, with `points_lengths` (B,) int64; with
      `pad_points`, (B, max P, 5) zero-padded instead (same lengths)
    - `img` (B, C, H, W, 3) uint8, `cam2img` / `lidar2cam` / `lidar2img` (B, C, 4, 4): stacked (a list when the
      shapes differ)
    - `gt_bboxes_3d`, `gt_labels_3d`, `num_lidar_pts`: lists of the items' arrays
    - `timestamp_us`, `lidar_sweeps`: (B,) int64; every other key (tokens): a list
    """
    if not items:
        raise ValueError("collate needs at least one item")
    batch: dict = {}
    for key in items[0]:
        values = [item[key] for item in items]
        if key == "points":
            lengths = np.array([len(v) for v in values], dtype=np.int64)
            batch["points_lengths"] = lengths
            if pad_points:
                padded = np.zeros((len(values), int(lengths.max(initial=0)), values[0].shape[1]), np.float32)
                for b, v in enumerate(values):
                    padded[b, :len(v)] = v
                batch[key] = padded
            else:
                batch[key] = np.concatenate(values).astype(np.float32, copy=False)
        elif key in STACKED:
            same = all(isinstance(v, np.ndarray) for v in values) and len({v.shape for v in values}) == 1
            batch[key] = np.stack(values) if same else values
        elif key in ("timestamp_us", "lidar_sweeps"):
            batch[key] = np.array(values, dtype=np.int64)
        else:
            batch[key] = values  # LISTED and the tokens
    return batch
