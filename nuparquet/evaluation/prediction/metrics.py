"""The devkit's prediction metrics (`nuscenes.eval.prediction.metrics`) over many agents at once: each mode's
average, final and largest displacement from the ground-truth future, the modes ranked by probability as the
devkit ranks them, and the min-over-top-k figures.

Agents are grouped by the shapes the devkit's arithmetic sees (modes, predicted steps, future steps), and each
group goes through the numpy calls the devkit makes for one agent, on stacked arrays: `np.linalg.norm(.., axis=-1)`
(the square root of the sum of two squares) and `np.mean`/`np.max` over the steps, so every number is the devkit's.
The ranking is the devkit's own call per agent, `np.flip(probabilities.argsort(axis=-1))` on the array it builds
(the same dtype): tied probabilities come out in the order numpy's default sort gives them on this machine, as they
do in the devkit."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ModeErrors:
    """Per agent, (M,) float64 per mode in submission order: ade_m (mean displacement over the steps), fde_m
    (displacement at the last step), max_m (the largest displacement)."""

    ade_m: list[np.ndarray]
    fde_m: list[np.ndarray]
    max_m: list[np.ndarray]


def mode_errors(predictions: list[np.ndarray], futures: list[np.ndarray]) -> ModeErrors:
    """The displacement errors of (M, T, 2) `predictions` against (L, 2) `futures` (T == L, or one of them 1: the
    devkit's broadcast), per group of agents of one shape."""
    n = len(predictions)
    out = ModeErrors([np.zeros(0)] * n, [np.zeros(0)] * n, [np.zeros(0)] * n)
    groups: dict[tuple, list[int]] = {}
    for i, (p, f) in enumerate(zip(predictions, futures)):
        groups.setdefault((p.shape, f.shape), []).append(i)
    for members in groups.values():
        pred = np.stack([predictions[i] for i in members])  # (G, M, T, 2)
        truth = np.stack([futures[i] for i in members])[:, None]  # (G, 1, L, 2), as np.repeat over modes
        distances = np.linalg.norm(pred - truth, axis=-1)  # (G, M, max(T, L))
        ade = np.mean(distances, axis=-1)
        largest = np.max(distances, axis=-1)
        fde = np.linalg.norm(pred[:, :, -1] - truth[:, :, -1], axis=-1)
        for j, i in enumerate(members):
            out.ade_m[i], out.fde_m[i], out.max_m[i] = ade[j], fde[j], largest[j]
    return out


def ranked_order(probabilities: np.ndarray) -> np.ndarray:
    """(M,) mode indices most probable first: the devkit's `rank_metric_over_top_k_modes` order."""
    return np.flip(probabilities.argsort(axis=-1), axis=-1)


def top_k(values: np.ndarray, order: np.ndarray, k_to_report) -> np.ndarray:
    """(len(k),) the least of `values` (M,) over the `order`'s first k modes for each k (all modes when k > M: the
    devkit's `desired_number_of_modes`); booleans (misses) give whether all k are True."""
    running = np.minimum.accumulate(values[order], axis=-1)
    return running[[min(k, len(order)) - 1 for k in k_to_report]]
