"""The fixed vocabulary of the synthetic dataset: nuScenes categories, attributes, visibility levels, sensor
channels with their calibration style, locations and vehicles.

Everything here follows the real nuScenes v1.0 release (names, lidarseg-era category `index`, channel names,
camera frame z forward / x right / y down, 1600x900 intrinsics, keyframe timing offsets), so code written for
nuScenes runs on the synthetic data unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Category:
    name: str
    index: int  # lidarseg label index of the real nuScenes category table
    description: str
    wlh_m: tuple[float, float, float]  # mean box size [width, length, height]
    group: str  # "vehicle", "cycle", "pedestrian" or "object": decides which attributes apply


CATEGORIES: tuple[Category, ...] = (
    Category("animal", 1, "All animals, e.g. cats, rats, dogs, deer, birds.", (0.36, 0.73, 0.51), "object"),
    Category("human.pedestrian.adult", 2, "Adult subcategory.", (0.67, 0.73, 1.77), "pedestrian"),
    Category("human.pedestrian.child", 3, "Child subcategory.", (0.51, 0.53, 1.38), "pedestrian"),
    Category("human.pedestrian.construction_worker", 4, "Construction worker", (0.72, 0.71, 1.74), "pedestrian"),
    Category("human.pedestrian.personal_mobility", 5,
             "A small electric or self-propelled vehicle, e.g. skateboard, segway, or scooter, on which the "
             "person typically travels in a upright position.", (0.62, 1.10, 1.65), "pedestrian"),
    Category("human.pedestrian.police_officer", 6, "Police officer.", (0.73, 0.72, 1.78), "pedestrian"),
    Category("human.pedestrian.stroller", 7,
             "Strollers. If a person is in the stroller, include in the annotation.", (0.63, 0.95, 1.17),
             "pedestrian"),
    Category("human.pedestrian.wheelchair", 8,
             "Wheelchairs. If a person is in the wheelchair, include in the annotation.", (0.77, 1.08, 1.37),
             "pedestrian"),
    Category("movable_object.barrier", 9,
             "Temporary road barrier placed in the scene in order to redirect traffic. Commonly used at "
             "construction sites. This includes concrete barrier, metal barrier and water barrier. No fences.",
             (2.53, 0.50, 0.98), "object"),
    Category("movable_object.debris", 10,
             "Movable object that is left on the driveable surface that is too large to be driven over safely, "
             "e.g tree branch, full trash bag etc.", (0.98, 0.86, 0.42), "object"),
    Category("movable_object.pushable_pullable", 11,
             "Objects that a pedestrian may push or pull. For example dolleys, wheel barrows, garbage-bins, or "
             "shopping carts.", (0.60, 0.67, 1.06), "object"),
    Category("movable_object.trafficcone", 12, "All types of traffic cone.", (0.41, 0.41, 1.07), "object"),
    Category("static_object.bicycle_rack", 13,
             "Area or device intended to park or secure the bicycles in a row. It includes all the bikes parked "
             "in it and any empty slots that are intended for parking bikes.", (1.60, 4.50, 1.10), "object"),
    Category("vehicle.bicycle", 14,
             "Human or electric powered 2-wheeled vehicle designed to travel at lower speeds either on road "
             "surface, sidewalks or bike paths.", (0.60, 1.70, 1.28), "cycle"),
    Category("vehicle.bus.bendy", 15, "Bendy bus subcategory. Annotate each section of the bendy bus "
             "individually.", (2.94, 17.00, 3.44), "vehicle"),
    Category("vehicle.bus.rigid", 16, "Rigid bus subcategory.", (2.95, 11.19, 3.49), "vehicle"),
    Category("vehicle.car", 17,
             "Vehicle designed primarily for personal use, e.g. sedans, hatch-backs, wagons, vans, mini-vans, "
             "SUVs and jeeps. If the vehicle is designed to carry more than 10 people use vehicle.bus. If it is "
             "primarily designed to haul cargo use vehicle.truck. ", (1.95, 4.62, 1.73), "vehicle"),
    Category("vehicle.construction", 18,
             "Vehicles primarily designed for construction. Typically very slow moving or stationary. Cranes "
             "and extremities of construction vehicles are only included in annotations if they interfere with "
             "traffic. Trucks used to haul rocks or building materials are considered vehicle.truck rather than "
             "construction vehicles.", (2.82, 6.50, 3.21), "vehicle"),
    Category("vehicle.emergency.ambulance", 19, "All types of ambulances.", (2.45, 6.52, 2.39), "vehicle"),
    Category("vehicle.emergency.police", 20,
             "All types of police vehicles including police bicycles and motorcycles.", (2.00, 5.00, 1.80),
             "vehicle"),
    Category("vehicle.motorcycle", 21,
             "Gasoline or electric powered 2-wheeled vehicle designed to move rapidly (at the speed of standard "
             "cars) on the road surface. This category includes all motorcycles, vespas and scooters.",
             (0.77, 2.11, 1.47), "cycle"),
    Category("vehicle.trailer", 22, "Any vehicle trailer, both for trucks, cars and bikes.", (2.92, 12.28, 3.87),
             "vehicle"),
    Category("vehicle.truck", 23,
             "Vehicles primarily designed to haul cargo including pick-ups, lorrys, trucks and semi-tractors. "
             "Trailers hauled after a semi-tractor should be labeled as vehicle.trailer", (2.52, 6.94, 2.84),
             "vehicle"),
)
CATEGORY_INDEX: dict[str, int] = {c.name: i for i, c in enumerate(CATEGORIES)}  # name -> position in CATEGORIES

# (name, description) in the order of the real attribute table.
ATTRIBUTES: tuple[tuple[str, str], ...] = (
    ("vehicle.moving", "Vehicle is moving."),
    ("vehicle.stopped", "Vehicle, with a driver/rider in/on it, is currently stationary but has an intent to move."),
    ("vehicle.parked", "Vehicle is stationary (usually for longer duration) with no immediate intent to move."),
    ("cycle.with_rider", "There is a rider on the bicycle or motorcycle."),
    ("cycle.without_rider", "There is NO rider on the bicycle or motorcycle."),
    ("pedestrian.sitting_lying_down", "The human is sitting or lying down."),
    ("pedestrian.standing", "The human is standing."),
    ("pedestrian.moving", "The human is moving."),
)
ATTRIBUTE_INDEX: dict[str, int] = {name: i for i, (name, _) in enumerate(ATTRIBUTES)}

# (token, level, description); nuScenes uses the level number as the token.
VISIBILITIES: tuple[tuple[str, str, str], ...] = (
    ("1", "v0-40", "visibility of whole object is between 0 and 40%"),
    ("2", "v40-60", "visibility of whole object is between 40 and 60%"),
    ("3", "v60-80", "visibility of whole object is between 60 and 80%"),
    ("4", "v80-100", "visibility of whole object is between 80 and 100%"),
)


@dataclass(frozen=True)
class Channel:
    """One sensor channel and the style of its calibration and timing (values like the real rig's)."""

    name: str
    modality: str  # "camera", "lidar" or "radar"
    translation_m: tuple[float, float, float]  # sensor origin in the ego frame
    yaw_deg: float  # heading of the sensor's forward axis in the ego frame (x forward, y left)
    keyframe_offset_us: int  # mean offset of this channel's keyframe from the sample (lidar) timestamp
    sweeps_per_interval: tuple[int, int]  # (min, max) sweeps between two keyframes: sets the sensor rate
    focal_px: float = 0.0  # cameras only: fx = fy
    fileformat: str = "pcd"
    size_px: tuple[int, int] = (0, 0)  # cameras only: image (width, height)

    @property
    def extension(self) -> str:
        return {"camera": ".jpg", "lidar": ".pcd.bin", "radar": ".pcd"}[self.modality]


CAMERA_WIDTH_PX, CAMERA_HEIGHT_PX = 1600, 900  # every nuScenes camera image
_NUSCENES_PX = (CAMERA_WIDTH_PX, CAMERA_HEIGHT_PX)

# Cameras fire in turn as the lidar sweeps past them, hence their staggered offsets before the lidar keyframe;
# 5 sweeps per 0.5 s interval is 12 Hz, 9 lidar sweeps 20 Hz, 5-6 radar sweeps ~13 Hz.
CHANNELS: tuple[Channel, ...] = (
    Channel("CAM_FRONT", "camera", (1.70, 0.01, 1.50), 0.0, -37_000, (5, 5), 1260.0, "jpg", _NUSCENES_PX),
    Channel("CAM_FRONT_RIGHT", "camera", (1.57, -0.50, 1.51), -56.5, -29_000, (5, 5), 1258.0, "jpg", _NUSCENES_PX),
    Channel("CAM_BACK_RIGHT", "camera", (1.04, -0.47, 1.55), -111.5, -21_000, (5, 5), 1254.0, "jpg", _NUSCENES_PX),
    Channel("CAM_BACK", "camera", (0.04, 0.01, 1.57), 180.0, -12_000, (5, 5), 803.0, "jpg", _NUSCENES_PX),
    Channel("CAM_BACK_LEFT", "camera", (1.04, 0.48, 1.57), 108.6, -2_000, (5, 5), 1256.0, "jpg", _NUSCENES_PX),
    Channel("CAM_FRONT_LEFT", "camera", (1.55, 0.50, 1.51), 55.3, -44_000, (5, 5), 1264.0, "jpg", _NUSCENES_PX),
    Channel("LIDAR_TOP", "lidar", (0.96, 0.0, 1.84), -90.0, 0, (9, 9)),
    Channel("RADAR_FRONT", "radar", (3.412, 0.0, 0.5), 0.0, 0, (5, 6)),
    Channel("RADAR_FRONT_LEFT", "radar", (2.422, 0.8, 0.78), 90.0, 0, (5, 6)),
    Channel("RADAR_FRONT_RIGHT", "radar", (2.422, -0.8, 0.77), -90.0, 0, (5, 6)),
    Channel("RADAR_BACK_LEFT", "radar", (-0.562, 0.628, 0.53), 175.0, 0, (5, 6)),
    Channel("RADAR_BACK_RIGHT", "radar", (-0.562, -0.618, 0.53), -175.0, 0, (5, 6)),
)
# A Lyft Level 5-like rig: seven cameras (a zoomed one beside CAM_FRONT; 1224x1024 images, the zoomed one
# 2048x864), three lidars (the roof one and two at the front corners), no radar.
LYFT_CHANNELS: tuple[Channel, ...] = (
    Channel("CAM_FRONT", "camera", (1.70, 0.0, 1.60), 0.0, -37_000, (5, 5), 880.0, "jpg", (1224, 1024)),
    Channel("CAM_FRONT_ZOOMED", "camera", (1.70, 0.15, 1.60), 0.0, -37_000, (5, 5), 2200.0, "jpg", (2048, 864)),
    Channel("CAM_FRONT_RIGHT", "camera", (1.55, -0.55, 1.55), -60.0, -29_000, (5, 5), 880.0, "jpg", (1224, 1024)),
    Channel("CAM_BACK_RIGHT", "camera", (0.90, -0.55, 1.55), -120.0, -21_000, (5, 5), 880.0, "jpg", (1224, 1024)),
    Channel("CAM_BACK", "camera", (0.0, 0.0, 1.60), 180.0, -12_000, (5, 5), 880.0, "jpg", (1224, 1024)),
    Channel("CAM_BACK_LEFT", "camera", (0.90, 0.55, 1.55), 120.0, -2_000, (5, 5), 880.0, "jpg", (1224, 1024)),
    Channel("CAM_FRONT_LEFT", "camera", (1.55, 0.55, 1.55), 60.0, -44_000, (5, 5), 880.0, "jpg", (1224, 1024)),
    Channel("LIDAR_TOP", "lidar", (1.0, 0.0, 1.90), -90.0, 0, (9, 9)),
    Channel("LIDAR_FRONT_LEFT", "lidar", (2.3, 0.8, 0.80), 45.0, 0, (9, 9)),
    Channel("LIDAR_FRONT_RIGHT", "lidar", (2.3, -0.8, 0.80), -45.0, 0, (9, 9)),
)
RIGS: dict[str, tuple[Channel, ...]] = {"nuscenes": CHANNELS, "lyft": LYFT_CHANNELS}  # `synthesize(rig=...)`
LIDAR_RING_ELEVATIONS_DEG = tuple(-30.67 + i * 4.0 / 3.0 for i in range(32))  # 32-beam spinning lidar, ring 0 lowest
KEYFRAME_INTERVAL_US = 500_000  # samples at 2 Hz


@dataclass(frozen=True)
class Location:
    name: str
    vehicles: tuple[str, ...]
    utc_offset_h: int
    drives_on_right: bool


LOCATIONS: tuple[Location, ...] = (
    Location("boston-seaport", ("n008", "n006"), -4, True),
    Location("singapore-onenorth", ("n015", "n010"), 8, False),
    Location("singapore-queenstown", ("n015", "n010"), 8, False),
    Location("singapore-hollandvillage", ("n015", "n010"), 8, False),
)
