"""mmdetection3d's nuScenes classes, name mapping and attributes (`NuScenesNameMapping`, `nus_categories`,
`nus_attributes`): category names -> the ten detection classes (-1 outside them)."""

from __future__ import annotations

import numpy as np

CLASSES = ("car", "truck", "trailer", "bus", "construction_vehicle", "bicycle", "motorcycle", "pedestrian",
           "traffic_cone", "barrier")
ATTRIBUTES = ("cycle.with_rider", "cycle.without_rider", "pedestrian.moving", "pedestrian.standing",
              "pedestrian.sitting_lying_down", "vehicle.moving", "vehicle.parked", "vehicle.stopped", "None")
NAME_MAPPING = {
    "movable_object.barrier": "barrier", "vehicle.bicycle": "bicycle", "vehicle.bus.bendy": "bus",
    "vehicle.bus.rigid": "bus", "vehicle.car": "car", "vehicle.construction": "construction_vehicle",
    "vehicle.motorcycle": "motorcycle", "human.pedestrian.adult": "pedestrian",
    "human.pedestrian.child": "pedestrian", "human.pedestrian.construction_worker": "pedestrian",
    "human.pedestrian.police_officer": "pedestrian", "movable_object.trafficcone": "traffic_cone",
    "vehicle.trailer": "trailer", "vehicle.truck": "truck",
}


def mapped_names(categories: np.ndarray) -> np.ndarray:
    """(A,) object array: the detection class of each category name, the category name itself when unmapped."""
    names = np.asarray(categories, dtype=object)
    out = names.copy()
    for source, target in NAME_MAPPING.items():
        out[names == source] = target
    return out


def label_of(categories: np.ndarray) -> np.ndarray:
    """(A,) int64 class index of each category name (via the mapping), -1 outside the ten classes."""
    names = mapped_names(categories)
    labels = np.full(len(names), -1, dtype=np.int64)
    for i, cls in enumerate(CLASSES):
        labels[names == cls] = i
    return labels
