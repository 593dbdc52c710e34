"""The nuScenes-lidarseg challenge classes, as nuscenes-devkit's `LidarsegClassMapper` (eval/lidarseg/utils.py)
defines them: 32 fine category names mapped onto 16 coarse classes plus the ignore class (index 0), and the fine
category index of each name taken from the dataset's `category` table (the devkit's `lidarseg_name2idx_mapping`:
each record's `index`)."""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.errors import InputError

IGNORE_NAME, IGNORE_INDEX = "ignore", 0

COARSE_INDEX = {IGNORE_NAME: IGNORE_INDEX, "barrier": 1, "bicycle": 2, "bus": 3, "car": 4, "construction_vehicle": 5,
                "motorcycle": 6, "pedestrian": 7, "traffic_cone": 8, "trailer": 9, "truck": 10,
                "driveable_surface": 11, "other_flat": 12, "sidewalk": 13, "terrain": 14, "manmade": 15,
                "vegetation": 16}
NUM_CLASSES = len(COARSE_INDEX)
COARSE_NAMES = tuple(COARSE_INDEX)  # by index: the order of the result dict's iou_per_class

FINE_TO_COARSE = {
    "noise": IGNORE_NAME, "human.pedestrian.adult": "pedestrian", "human.pedestrian.child": "pedestrian",
    "human.pedestrian.wheelchair": IGNORE_NAME, "human.pedestrian.stroller": IGNORE_NAME,
    "human.pedestrian.personal_mobility": IGNORE_NAME, "human.pedestrian.police_officer": "pedestrian",
    "human.pedestrian.construction_worker": "pedestrian", "animal": IGNORE_NAME, "vehicle.car": "car",
    "vehicle.motorcycle": "motorcycle", "vehicle.bicycle": "bicycle", "vehicle.bus.bendy": "bus",
    "vehicle.bus.rigid": "bus", "vehicle.truck": "truck", "vehicle.construction": "construction_vehicle",
    "vehicle.emergency.ambulance": IGNORE_NAME, "vehicle.emergency.police": IGNORE_NAME,
    "vehicle.trailer": "trailer", "movable_object.barrier": "barrier", "movable_object.trafficcone": "traffic_cone",
    "movable_object.pushable_pullable": IGNORE_NAME, "movable_object.debris": IGNORE_NAME,
    "static_object.bicycle_rack": IGNORE_NAME, "flat.driveable_surface": "driveable_surface",
    "flat.sidewalk": "sidewalk", "flat.terrain": "terrain", "flat.other": "other_flat", "static.manmade": "manmade",
    "static.vegetation": "vegetation", "static.other": IGNORE_NAME, "vehicle.ego": IGNORE_NAME}


def fine_to_coarse_lookup(dataset) -> np.ndarray:
    """(F,) int64: the coarse class index of each fine lidarseg index (F = the largest `index` of the `category`
    table + 1; -1 where no category has that index). InputError for a category the devkit's mapper does not know
    (its `get_fine_idx_2_coarse_idx` raises KeyError there) or a table without `index` (no lidarseg categories)."""
    table = dataset.scan("tables/category")
    if "index" not in table.collect_schema().names():
        raise InputError(f"{dataset.root}: the category table has no `index` column (a dataset without "
                         "nuScenes-lidarseg categories)")
    rows = table.select("name", "index").filter(pl.col("index").is_not_null()).collect()
    unknown = [name for name in rows["name"].to_list() if name not in FINE_TO_COARSE]
    if unknown:
        raise InputError(f"category {unknown[0]!r} has a lidarseg index but is none of the devkit's lidarseg "
                         "classes (LidarsegClassMapper cannot map it)")
    indices = rows["index"].to_numpy()
    lookup = np.full(int(indices.max()) + 1 if len(indices) else 0, -1, dtype=np.int64)
    # the devkit's name -> index dict keeps the last record of a name; an index -> coarse dict the last of an index
    for name, index in dict(zip(rows["name"].to_list(), indices.tolist())).items():
        lookup[index] = COARSE_INDEX[FINE_TO_COARSE[name]]
    return lookup
