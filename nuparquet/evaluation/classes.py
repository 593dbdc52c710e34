"""The detection vocabularies, as the devkits' `eval/detection/constants.py` and `utils.py` define them: nuScenes'
(nuscenes-devkit: ten classes, eight attributes; and the tracking classes of `eval/tracking/utils.py`) and MAN
TruckScenes' (truckscenes-devkit: twelve classes, eleven attributes), each a `Taxonomy`: which categories map to
which class, which true-positive errors a class has no use for, and which orientations are only defined up to
180 degrees. The module-level names are nuScenes' (`NUSCENES` gathers them)."""

from __future__ import annotations

import math
from dataclasses import dataclass

DETECTION_NAMES = ("car", "truck", "bus", "trailer", "construction_vehicle", "pedestrian", "motorcycle", "bicycle",
                   "traffic_cone", "barrier")

ATTRIBUTE_NAMES = ("pedestrian.moving", "pedestrian.sitting_lying_down", "pedestrian.standing", "cycle.with_rider",
                   "cycle.without_rider", "vehicle.moving", "vehicle.parked", "vehicle.stopped")

# devkit `category_to_detection_name`: pedestrian leaves out personal_mobility, stroller and wheelchair; every
# category not listed (animal, debris, pushable_pullable, bicycle_rack, ambulance, police, ...) is not evaluated.
CATEGORY_TO_DETECTION = {
    "movable_object.barrier": "barrier",
    "vehicle.bicycle": "bicycle",
    "vehicle.bus.bendy": "bus",
    "vehicle.bus.rigid": "bus",
    "vehicle.car": "car",
    "vehicle.construction": "construction_vehicle",
    "vehicle.motorcycle": "motorcycle",
    "human.pedestrian.adult": "pedestrian",
    "human.pedestrian.child": "pedestrian",
    "human.pedestrian.construction_worker": "pedestrian",
    "human.pedestrian.police_officer": "pedestrian",
    "movable_object.trafficcone": "traffic_cone",
    "vehicle.trailer": "trailer",
    "vehicle.truck": "truck",
}

# devkit `filter_eval_boxes`: bicycles and motorcycles whose centre lies in a bicycle rack of their sample are
# not evaluated (ground truth and predictions alike).
BIKE_RACK_CATEGORY = "static_object.bicycle_rack"
CYCLE_CLASSES = ("bicycle", "motorcycle")

TP_METRICS = ("trans_err", "scale_err", "orient_err", "vel_err", "attr_err")

# devkit `DetectionEval.evaluate`: errors a class reports as NaN (its orientation, velocity or attribute means
# nothing), and `accumulate`: a barrier's orientation is only defined up to 180 degrees.
UNDEFINED_TP_METRICS = {"traffic_cone": ("attr_err", "vel_err", "orient_err"), "barrier": ("attr_err", "vel_err")}
ORIENTATION_PERIOD_RAD = {"barrier": math.pi}  # every other class: 2 pi

PRETTY_DETECTION_NAMES = {"car": "Car", "truck": "Truck", "bus": "Bus", "trailer": "Trailer",
                          "construction_vehicle": "Constr. Veh.", "pedestrian": "Pedestrian",
                          "motorcycle": "Motorcycle", "bicycle": "Bicycle", "traffic_cone": "Traffic Cone",
                          "barrier": "Barrier"}
PRETTY_TP_METRICS = {"trans_err": "Trans.", "scale_err": "Scale", "orient_err": "Orient.", "vel_err": "Vel.",
                     "attr_err": "Attr."}
TP_METRICS_UNITS = {"trans_err": "m", "scale_err": "1-IOU", "orient_err": "rad.", "vel_err": "m/s",
                    "attr_err": "1-acc."}
# the names `DetectionEval.main` prints for the mean TP errors
MEAN_TP_NAMES = {"trans_err": "mATE", "scale_err": "mASE", "orient_err": "mAOE", "vel_err": "mAVE",
                 "attr_err": "mAAE"}


def orientation_period_rad(detection_name: str, periods: dict[str, float] = ORIENTATION_PERIOD_RAD) -> float:
    return periods.get(detection_name, 2 * math.pi)

# The tracking challenge (devkit `eval/tracking/utils.py::category_to_tracking_name`): seven classes, the detection
# mapping less the static ones (barrier, traffic cone) and construction vehicles.
TRACKING_NAMES = ("bicycle", "bus", "car", "motorcycle", "pedestrian", "trailer", "truck")
CATEGORY_TO_TRACKING = {category: name for category, name in CATEGORY_TO_DETECTION.items() if name in TRACKING_NAMES}


@dataclass(frozen=True)
class Taxonomy:
    """One devkit's detection benchmark vocabulary.

    family: the source format whose devkit defines it (`Dataset.source_format`); detection_names: its classes in
    the devkit's order; attribute_names: what a box's attribute_name may be ('' aside); category_to_detection:
    category name -> class (categories not listed are not evaluated); undefined_tp_metrics: {class: errors reported
    as NaN}; orientation_period_rad: {class: period} (2 pi otherwise); reference_channel: the keyframe whose ego
    pose the class ranges are measured from (None: the dataset's reference lidar, LIDAR_TOP in nuScenes);
    tagged_output: the devkit writes its metrics per scene tag (TruckScenes' `DetectionMetricsList`: the
    metrics under "all", and metrics_details keyed "all:<class>"); scene_tags, unevaluated_tags: its per-tag
    evaluation (`evaluate_tags`).
    """

    family: str
    detection_names: tuple[str, ...]
    attribute_names: tuple[str, ...]
    category_to_detection: dict[str, str]
    undefined_tp_metrics: dict[str, tuple[str, ...]]
    orientation_period_rad: dict[str, float]
    pretty_names: dict[str, str]
    reference_channel: str | None = None
    tagged_output: bool = False
    scene_tags: tuple[str, ...] = ()  # the tags a scene's description may hold, evaluated one by one on request
    unevaluated_tags: tuple[str, ...] = ()  # tags whose metrics the devkit reports as NaN (too few scenes)

    @property
    def colors(self) -> dict[str, str]:
        """{class: matplotlib colour}: the devkit's DETECTION_COLORS, "C<i>" by the class's place."""
        return {name: f"C{i}" for i, name in enumerate(self.detection_names)}

    def period_rad(self, detection_name: str) -> float:
        return orientation_period_rad(detection_name, self.orientation_period_rad)


NUSCENES = Taxonomy("nuscenes", DETECTION_NAMES, ATTRIBUTE_NAMES, CATEGORY_TO_DETECTION, UNDEFINED_TP_METRICS,
                    ORIENTATION_PERIOD_RAD, PRETTY_DETECTION_NAMES)

# truckscenes-devkit 1.2.0 `eval/detection/constants.py`, `utils.category_to_detection_name` (the ego truck's own
# trailer is a trailer; construction and other vehicles are other_vehicle) and `evaluate.py`: a traffic sign has no
# velocity error and, like a barrier, an orientation up to 180 degrees; an animal has no attribute error. The
# ranges are measured from the LIDAR_LEFT keyframe's ego pose (its `add_center_dist`).
TRUCKSCENES = Taxonomy(
    "truckscenes",
    ("car", "truck", "bus", "trailer", "other_vehicle", "pedestrian", "motorcycle", "bicycle", "traffic_cone",
     "barrier", "animal", "traffic_sign"),
    (*ATTRIBUTE_NAMES, "traffic_sign.pole_mounted", "traffic_sign.overhanging", "traffic_sign.temporary"),
    {"animal": "animal", **{c: n for c, n in CATEGORY_TO_DETECTION.items() if n != "construction_vehicle"},
     "vehicle.construction": "other_vehicle", "vehicle.other": "other_vehicle",
     "static_object.traffic_sign": "traffic_sign", "vehicle.ego_trailer": "trailer"},
    {"traffic_cone": ("attr_err", "vel_err", "orient_err"), "barrier": ("attr_err", "vel_err"),
     "animal": ("attr_err",), "traffic_sign": ("vel_err",)},
    {"barrier": math.pi, "traffic_sign": math.pi},
    {**{n: p for n, p in PRETTY_DETECTION_NAMES.items() if n != "construction_vehicle"},
     "other_vehicle": "Other Veh.", "animal": "Animal", "traffic_sign": "Traffic Sign"},
    reference_channel="LIDAR_LEFT", tagged_output=True,
    # truckscenes-devkit `eval/common/constants.py` TAG_NAMES, and the tags `DetectionEval.evaluate` gives NaN
    scene_tags=("weather.clear", "weather.rain", "weather.snow", "weather.fog", "weather.hail", "weather.overcast",
                "weather.other_weather", "area.highway", "area.rural", "area.terminal", "area.parking", "area.city",
                "area.residential", "area.other_area", "daytime.morning", "daytime.noon", "daytime.evening",
                "daytime.night", "season.spring", "season.summer", "season.autumn", "season.winter",
                "lighting.illuminated", "lighting.glare", "lighting.dark", "lighting.twilight",
                "lighting.other_lighting", "structure.tunnel", "structure.bridge", "structure.underpass",
                "structure.overpass", "structure.regular", "construction.roadworks", "construction.unchanged"),
    unevaluated_tags=("weather.other_weather", "weather.snow", "weather.hail", "area.parking", "area.other_area",
                      "season.spring", "lighting.other_lighting"))

TAXONOMIES = {t.family: t for t in (NUSCENES, TRUCKSCENES)}


def taxonomy_of(class_names) -> Taxonomy | None:
    """The taxonomy whose classes are exactly `class_names` (in any order), None if none is."""
    return next((t for t in TAXONOMIES.values() if set(class_names) == set(t.detection_names)), None)
