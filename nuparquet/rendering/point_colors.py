"""How points are coloured, as the devkit colours them: a number through viridis scaled to its range (matplotlib's
`scatter(c=values)`), lidar intensity (`render_intensity`'s scaling), a lidarseg class (the devkit colormap,
`palette.category_rgb`), a Panoptic nuScenes label (`generate_panoptic_colors`: a colour per instance from its seeded
table, stuff classes in their class colour), and the class filter (`filter_lidarseg_labels`: other points hidden).

Colours are RGB uint8 here; drawing code converts to OpenCV's BGR (`draw.rgb_to_bgr`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import lru_cache

import cv2
import numpy as np

from nuparquet.rendering.palette import CHALLENGE_CLASS_RGB, category_rgb

PANOPTIC_DIVISOR = 1000  # panoptic label = class index * 1000 + instance id
# The devkit's first "stuff" class index (panoptic_utils.STUFF_START_CLASS_ID): Panoptic nuScenes' class order puts
# the things (0-23) before the stuff (24-31); stuff points take their class colour, things one per instance.
STUFF_START_CLASS_ID = 24
PANOPTIC_COLOURS = 32000  # generate_panoptic_colors' max_instances

_VIRIDIS_RGB = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_VIRIDIS)[:, 0, ::-1].copy()


def scalar_rgb(values, vmin: float | None = None, vmax: float | None = None) -> np.ndarray:
    """(N,) numbers -> (N, 3) uint8 RGB through viridis, scaled from `vmin` (default: the smallest value) to `vmax`
    (default: the largest), as matplotlib's `scatter(c=values)` colours them."""
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    if not len(values):
        return np.zeros((0, 3), np.uint8)
    lo = float(np.nanmin(values)) if vmin is None else vmin
    hi = float(np.nanmax(values)) if vmax is None else vmax
    scaled = (values - lo) / (hi - lo) if hi > lo else np.zeros_like(values)
    return _VIRIDIS_RGB[np.clip(np.nan_to_num(scaled) * 255.0, 0, 255).astype(np.uint8)]


def intensity_levels(intensity: np.ndarray) -> np.ndarray:
    """(P,) values in [0, 0.5] the devkit colours by when `render_intensity=True`: min-max scaled over the whole
    cloud, to the power 0.1, minus 0.5, floored at 0."""
    intensity = np.asarray(intensity, dtype=np.float64)
    span = intensity.max() - intensity.min() if intensity.size else 0.0
    scaled = (intensity - intensity.min()) / span if span > 0 else np.zeros_like(intensity)
    return np.maximum(0.0, scaled ** 0.1 - 0.5)


def class_of(labels: np.ndarray, mode: str) -> np.ndarray:
    """(P,) class index of each label: the lidarseg label itself, or a panoptic label // 1000."""
    labels = np.asarray(labels, dtype=np.int64)
    return labels if mode == "lidarseg" else labels // PANOPTIC_DIVISOR


@lru_cache(maxsize=1)
def _panoptic_table() -> np.ndarray:
    """The devkit's random part of `generate_panoptic_colors`: `np.random.seed(0)` then uniform (32000, 3) in [0, 1)
    (the legacy generator, drawn here without touching numpy's global state)."""
    return np.random.RandomState(0).uniform(low=0.0, high=1.0, size=(PANOPTIC_COLOURS, 3))


def label_rgb(labels: np.ndarray, mode: str, names_by_index: Mapping[int, str]) -> np.ndarray:
    """(P, 3) uint8 RGB of point labels.

    lidarseg: the class colour of the devkit colormap (`category_rgb` of the class name, `names_by_index`).
    panoptic: the devkit's `generate_panoptic_colors` table: a stuff label (class >= 24, instance 0) in its class
    colour, 0 in the noise colour, every other label (each thing instance) its seeded random colour.
    """
    labels = np.asarray(labels, dtype=np.int64).reshape(-1)
    unique, inverse = np.unique(labels, return_inverse=True)
    colours = np.zeros((unique.size, 3), dtype=np.uint8)
    table = _panoptic_table() if mode == "panoptic" else None
    for k, label in enumerate(unique.tolist()):
        if mode == "lidarseg":
            colours[k] = category_rgb(names_by_index.get(label, f"class {label}"))
            continue
        index, instance = divmod(label, PANOPTIC_DIVISOR)
        if label == 0:
            colours[k] = category_rgb("noise")
        elif instance == 0 and index >= STUFF_START_CLASS_ID and index in names_by_index:
            colours[k] = category_rgb(names_by_index[index])
        elif 0 <= label < PANOPTIC_COLOURS:
            colours[k] = np.rint(table[label] * 255.0).astype(np.uint8)
        else:  # beyond the devkit's table (it would index out of range): the class colour
            colours[k] = category_rgb(names_by_index.get(index, f"class {index}"))
    return colours[inverse.reshape(-1)]


# The challenge classes in index order (0: ignore; 1-10 things, 11-16 stuff: the panoptic challenge's split).
_CHALLENGE_RGB = np.array(list(CHALLENGE_CLASS_RGB.values()), dtype=np.uint8)
CHALLENGE_STUFF_START = 11


def challenge_label_rgb(labels: np.ndarray, mode: str) -> np.ndarray:
    """(P, 3) uint8 RGB of predicted labels in the challenge classes (a lidarseg or panoptic submission): a lidarseg
    class, or a panoptic label of a stuff class (11-16) or of the ignore class, in the devkit's coarse colour; a
    panoptic label of a thing class (1-10) in its colour of `generate_panoptic_colors`' table (one per instance,
    as the ground truth's instances); a class outside 0..16 in a hashed colour."""
    labels = np.asarray(labels, dtype=np.int64).reshape(-1)
    classes = class_of(labels, mode)
    known = (classes >= 0) & (classes < len(_CHALLENGE_RGB))
    colours = np.zeros((len(labels), 3), dtype=np.uint8)
    colours[known] = _CHALLENGE_RGB[classes[known]]
    for label in np.unique(classes[~known]).tolist():
        colours[classes == label] = category_rgb(f"class {label}")
    if mode == "panoptic":
        thing = (classes > 0) & (classes < CHALLENGE_STUFF_START) & (labels < PANOPTIC_COLOURS)
        colours[thing] = np.rint(_panoptic_table()[labels[thing]] * 255.0).astype(np.uint8)
    return colours


def class_filter(labels: np.ndarray, mode: str, keep_classes: Sequence[int] | None, n_classes: int) -> np.ndarray:
    """(P,) bool: points of the classes `keep_classes` (all points for None or an empty list, as the devkit shows
    them). ValueError for an index outside 0..n_classes-1, as the devkit's assertion."""
    labels = np.asarray(labels)
    if not keep_classes:
        return np.ones(len(labels), dtype=bool)
    bad = [c for c in keep_classes if not 0 <= int(c) < n_classes]
    if bad:
        raise ValueError(f"filter_lidarseg_labels: class indices must be in 0..{n_classes - 1}, got {bad}")
    return np.isin(class_of(labels, mode), np.asarray(list(keep_classes), dtype=np.int64))


def legend_classes(shown_labels: np.ndarray, mode: str, keep_classes: Sequence[int] | None,
                   names_by_index: Mapping[int, str]) -> list[int]:
    """The class indices a legend lists, as the devkit picks them: the filter when one is given, else the classes
    among the points drawn (lidarseg); for panoptic only stuff classes (the filter's, or all of them)."""
    n_classes = max(names_by_index) + 1 if names_by_index else 0
    if keep_classes:
        chosen = sorted({int(c) for c in keep_classes})
    elif mode == "lidarseg":
        chosen = sorted(set(class_of(shown_labels, mode).tolist()))
    else:
        chosen = list(range(STUFF_START_CLASS_ID, n_classes))
    if mode == "panoptic":
        chosen = [c for c in chosen if c >= STUFF_START_CLASS_ID]
    return [c for c in chosen if c in names_by_index]
