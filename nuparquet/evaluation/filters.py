"""Which boxes the evaluation keeps: the devkit's `add_center_dist` and `filter_eval_boxes`, vectorised, for
ground truth and predictions alike.

In the devkit's order, a box is left out when
1. its xy distance to the ego vehicle is not below its class's range (`ego_dist < class_range`, strictly),
   the ego position being that of the sample's reference-lidar keyframe (LIDAR_TOP in nuScenes);
2. it holds no lidar or radar point (`num_pts == 0`; predictions say -1, "not counted", unless they give one);
3. it is a bicycle or motorcycle whose centre lies in a bicycle rack annotated in its sample (the devkit's
   `points_in_box` test: faces included).
"""

from __future__ import annotations

import numpy as np

from nuparquet.evaluation.boxes import Boxes
from nuparquet.geometry import box_corners

KEPT, OUT_OF_RANGE, NO_POINTS, IN_BIKE_RACK = 0, 1, 2, 3
REASONS = (None, "range", "points", "bike_rack")  # the `filtered_by` column of the predictions/ground truth


def ego_distances_m(boxes: Boxes, ego_xyz_m: np.ndarray) -> np.ndarray:
    """(N,) xy distance of each box centre to the ego position of its sample ((S, 3) per sample), with the
    devkit's arithmetic: sqrt(dx^2 + dy^2) of the differences of the global coordinates."""
    d = boxes.translation_m[:, :2] - ego_xyz_m[boxes.sample_index, :2]
    return np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2)


def filter_reasons(boxes: Boxes, ego_distance_m: np.ndarray, class_range_m: np.ndarray, cycle_class: np.ndarray,
                   racks: Boxes) -> np.ndarray:
    """(N,) int8: KEPT, or the first filter (in the devkit's order) that leaves the box out.

    class_range_m: (C,) range of each class; cycle_class: (C,) bool, the classes the rack filter applies to;
    racks: the bicycle-rack annotations of the evaluated samples (sample_index, translation, size, rotation).
    """
    reason = np.full(len(boxes), KEPT, dtype=np.int8)
    out_of_range = ~(ego_distance_m < class_range_m[boxes.class_index])
    reason[out_of_range] = OUT_OF_RANGE
    reason[(reason == KEPT) & (boxes.num_pts == 0)] = NO_POINTS
    candidates = np.flatnonzero((reason == KEPT) & cycle_class[boxes.class_index])
    reason[candidates[centres_in_racks(boxes.take(candidates), racks)]] = IN_BIKE_RACK
    return reason


def centres_in_racks(boxes: Boxes, racks: Boxes) -> np.ndarray:
    """(N,) bool: the box centre lies in (or on) a rack box of the same sample (devkit `points_in_box`)."""
    inside = np.zeros(len(boxes), dtype=bool)
    if not len(boxes) or not len(racks):
        return inside
    order = np.argsort(racks.sample_index, kind="stable")
    rack_samples = racks.sample_index[order]
    first = np.searchsorted(rack_samples, boxes.sample_index, "left")
    n = np.searchsorted(rack_samples, boxes.sample_index, "right") - first
    box = np.repeat(np.arange(len(boxes)), n)  # every (box, rack of its sample) pair
    rack = order[np.repeat(first, n) + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)]
    if not len(box):
        return inside
    corners = box_corners(racks.translation_m, racks.size_wlh_m, racks.rotation_wxyz)[rack]  # (K, 8, 3)
    p1 = corners[:, 0]
    v = boxes.translation_m[box] - p1  # subtracted first, as the devkit does
    hit = np.ones(len(box), dtype=bool)
    for corner in (4, 1, 3):  # the edges to p_x, p_y, p_z
        edge = corners[:, corner] - p1
        along = np.einsum("kc,kc->k", edge, v)
        hit &= (along >= 0) & (along <= np.einsum("kc,kc->k", edge, edge))
    inside[box[hit]] = True
    return inside
