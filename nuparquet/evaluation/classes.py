"""The nuScenes detection vocabulary, as nuscenes-devkit's `eval/detection/constants.py` and `utils.py` define it
(and the tracking classes of `eval/tracking/utils.py`, at the end):
the ten detection classes, the eight attributes, which categories map to which class, and which true-positive
errors a class has no use for."""

from __future__ import annotations

import math

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
DETECTION_COLORS = {name: f"C{i}" for i, name in enumerate(DETECTION_NAMES)}
PRETTY_TP_METRICS = {"trans_err": "Trans.", "scale_err": "Scale", "orient_err": "Orient.", "vel_err": "Vel.",
                     "attr_err": "Attr."}
TP_METRICS_UNITS = {"trans_err": "m", "scale_err": "1-IOU", "orient_err": "rad.", "vel_err": "m/s",
                    "attr_err": "1-acc."}
# the names `DetectionEval.main` prints for the mean TP errors
MEAN_TP_NAMES = {"trans_err": "mATE", "scale_err": "mASE", "orient_err": "mAOE", "vel_err": "mAVE",
                 "attr_err": "mAAE"}


def orientation_period_rad(detection_name: str) -> float:
    return ORIENTATION_PERIOD_RAD.get(detection_name, 2 * math.pi)

# The tracking challenge (devkit `eval/tracking/utils.py::category_to_tracking_name`): seven classes, the detection
# mapping less the static ones (barrier, traffic cone) and construction vehicles.
TRACKING_NAMES = ("bicycle", "bus", "car", "motorcycle", "pedestrian", "trailer", "truck")
CATEGORY_TO_TRACKING = {category: name for category, name in CATEGORY_TO_DETECTION.items() if name in TRACKING_NAMES}
