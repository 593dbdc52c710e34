"""Category colours: the nuscenes-devkit palette (`nuscenes.utils.color_map.get_colormap()`), copied so that
nuparquet never imports the devkit at runtime.

The synthetic generator paints each box in its category's colour and the renderer draws overlays with the
same colours, so a correct overlay visibly lines up with the painted cuboid.
"""

from __future__ import annotations

import hashlib

# RGB, exactly as in nuscenes-devkit 1.2.0 `get_colormap()` (object classes and the lidarseg stuff classes).
CATEGORY_RGB: dict[str, tuple[int, int, int]] = {
    "noise": (0, 0, 0),
    "animal": (70, 130, 180),
    "human.pedestrian.adult": (0, 0, 230),
    "human.pedestrian.child": (135, 206, 235),
    "human.pedestrian.construction_worker": (100, 149, 237),
    "human.pedestrian.personal_mobility": (219, 112, 147),
    "human.pedestrian.police_officer": (0, 0, 128),
    "human.pedestrian.stroller": (240, 128, 128),
    "human.pedestrian.wheelchair": (138, 43, 226),
    "movable_object.barrier": (112, 128, 144),
    "movable_object.debris": (210, 105, 30),
    "movable_object.pushable_pullable": (105, 105, 105),
    "movable_object.trafficcone": (47, 79, 79),
    "static_object.bicycle_rack": (188, 143, 143),
    "vehicle.bicycle": (220, 20, 60),
    "vehicle.bus.bendy": (255, 127, 80),
    "vehicle.bus.rigid": (255, 69, 0),
    "vehicle.car": (255, 158, 0),
    "vehicle.construction": (233, 150, 70),
    "vehicle.emergency.ambulance": (255, 83, 0),
    "vehicle.emergency.police": (255, 215, 0),
    "vehicle.motorcycle": (255, 61, 99),
    "vehicle.trailer": (255, 140, 0),
    "vehicle.truck": (255, 99, 71),
    "flat.driveable_surface": (0, 207, 191),
    "flat.other": (175, 0, 75),
    "flat.sidewalk": (75, 0, 75),
    "flat.terrain": (112, 180, 60),
    "static.manmade": (222, 184, 135),
    "static.other": (255, 228, 196),
    "static.vegetation": (0, 175, 0),
    "vehicle.ego": (255, 240, 245),
}

# RGB, exactly as truckscenes-devkit 1.2.0's `get_colormap()` (its order too): nuScenes' object classes in their
# colours, its traffic sign after the bicycle rack, and its own vehicles last.
_NUSCENES_OBJECTS = list(CATEGORY_RGB)[1:list(CATEGORY_RGB).index("flat.driveable_surface")]  # animal .. vehicle.truck
_BEFORE_BICYCLE = _NUSCENES_OBJECTS.index("vehicle.bicycle")
TRUCKSCENES_RGB: dict[str, tuple[int, int, int]] = {
    **{name: CATEGORY_RGB[name] for name in _NUSCENES_OBJECTS[:_BEFORE_BICYCLE]},
    "static_object.traffic_sign": (222, 184, 135),
    **{name: CATEGORY_RGB[name] for name in _NUSCENES_OBJECTS[_BEFORE_BICYCLE:]},
    "vehicle.train": (255, 228, 196),
    "vehicle.other": (255, 240, 245),
    "vehicle.ego_trailer": (0, 0, 0),
}

# RGB of the 16 lidarseg challenge classes and the ignore class, exactly as nuscenes-devkit 1.2.0's
# `LidarsegClassMapper.get_coarse2color()` (the classes a lidarseg or panoptic submission predicts).
CHALLENGE_CLASS_RGB: dict[str, tuple[int, int, int]] = {
    "ignore": (0, 0, 0), "barrier": (112, 128, 144), "bicycle": (220, 20, 60), "bus": (255, 127, 80),
    "car": (255, 158, 0), "construction_vehicle": (233, 150, 70), "motorcycle": (255, 61, 99),
    "pedestrian": (0, 0, 230), "traffic_cone": (47, 79, 79), "trailer": (255, 140, 0), "truck": (255, 99, 71),
    "driveable_surface": (0, 207, 191), "other_flat": (175, 0, 75), "sidewalk": (75, 0, 75),
    "terrain": (112, 180, 60), "manmade": (222, 184, 135), "vegetation": (0, 175, 0),
}


def category_rgb(name: str) -> tuple[int, int, int]:
    """RGB colour of a category; names outside the devkit palette (Lyft, T4, ... taxonomies) get a colour
    derived from a hash of the name, so it is the same in every run, process and tool."""
    rgb = CATEGORY_RGB.get(name)
    if rgb is not None:
        return rgb
    digest = hashlib.md5(name.encode("utf-8")).digest()
    # Keep every channel in 40..215 so the colour stays visible on both dark and light backgrounds.
    return tuple(40 + b % 176 for b in digest[:3])  # type: ignore[return-value]


def _hex(code: str) -> tuple[int, int, int]:
    return int(code[1:3], 16), int(code[3:5], 16), int(code[5:7], 16)


# RGB of the map layers as nuscenes-devkit 1.2.0's `NuScenesMapExplorer` draws them (its default `color_map`).
MAP_LAYER_RGB: dict[str, tuple[int, int, int]] = {
    layer: _hex(code) for layer, code in {
        "drivable_area": "#a6cee3", "road_segment": "#1f78b4", "road_block": "#b2df8a", "lane": "#33a02c",
        "ped_crossing": "#fb9a99", "walkway": "#e31a1c", "stop_line": "#fdbf6f", "carpark_area": "#ff7f00",
        "road_divider": "#cab2d6", "lane_divider": "#6a3d9a", "traffic_light": "#7e772e",
    }.items()
}
# matplotlib's default colour cycle ("tab10"): the devkit's render_centerlines draws lane i in colour i % 10.
LINE_CYCLE_RGB: tuple[tuple[int, int, int], ...] = tuple(_hex(c) for c in (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"))
