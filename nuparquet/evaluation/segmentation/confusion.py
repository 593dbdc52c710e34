"""nuscenes-devkit's `ConfusionMatrix` (eval/lidarseg/utils.py) and `LidarSegEval.evaluate`'s result dict, with
the same numpy operations in the same order, so every value is the devkit's bit for bit: the (C, C) int64 counts
of `bincount(C * gt + pred)` with the ignore row and column zeroed, summed over the frames; IoU as
intersection / union cast to float32 (the devkit's cast: a union above 2**24 points is rounded there too); mIoU
as `nanmean`; frequency-weighted IoU as `nansum(points_per_class * iou) / points`."""

from __future__ import annotations

import numpy as np

from nuparquet.evaluation.segmentation.classes import COARSE_NAMES, IGNORE_INDEX, NUM_CLASSES


def frame_confusion(gt: np.ndarray, pred: np.ndarray, num_classes: int = NUM_CLASSES,
                    ignore_index: int | None = IGNORE_INDEX) -> np.ndarray:
    """(C, C) int64: points of ground-truth class (row) predicted as class (column) in one frame; `gt`, `pred`:
    (P,) coarse class indices, already checked to be in range (the caller names the frame when they are not)."""
    label = num_classes * gt.astype("int") + pred
    confusion = np.bincount(label, minlength=num_classes ** 2).reshape(num_classes, num_classes)
    if ignore_index is not None:
        confusion[ignore_index, :] = 0
        confusion[:, ignore_index] = 0
    return confusion


def per_class_iou(confusion: np.ndarray) -> np.ndarray:
    """(C,) float64: IoU per class (NaN where a class is neither in the ground truth nor predicted, and for the
    ignore class)."""
    intersection = np.diagonal(confusion)
    union = confusion.sum(axis=1) + confusion.sum(axis=0) - intersection
    with np.errstate(divide="ignore", invalid="ignore"):
        return intersection / (union.astype(np.float32))


def lidarseg_metrics(confusion: np.ndarray) -> dict:
    """`LidarSegEval.evaluate`'s result dict: {"iou_per_class": {class name: IoU, in index order, "ignore"
    first}, "miou": ..., "freq_weighted_iou": ...} (Python floats; NaN where the devkit has NaN)."""
    iou = per_class_iou(confusion)
    freq_weighted = np.nansum(confusion.sum(axis=1) * iou) / confusion.sum()
    return {"iou_per_class": {name: float(value) for name, value in zip(COARSE_NAMES, iou)},
            "miou": float(np.nanmean(iou)),
            "freq_weighted_iou": float(freq_weighted)}
