"""The devkit's box calls on a `nuparquet.devkit.NuScenes`: `get_box`, `get_boxes`, `get_sample_data`, `box_velocity`.

Which boxes a frame shows is the devkit's rule, as `nuparquet.frames.boxes` applies it over many frames: a keyframe
(or a frame of a sample without a previous sample) shows its sample's annotations; a sweep shows each annotation
moved to the sweep's time between the same instance's annotation in the previous sample and this one.

The numbers are the devkit's own, operation for operation: the centre interpolated as `np.interp` does
(`nuparquet.geometry.interp_two_points`), the rotation by pyquaternion's `slerp`, and each `Box` moved into the
sensor (or flat ego) frame with the very quaternion products of `Box.translate` / `Box.rotate`. The one shortcut:
for a camera, the boxes no corner of which can be in the image are found first for all boxes at once with
nuparquet's geometry (`nuparquet.geometry`, with a 1e-6 m / 1e-3 px margin, far above its rounding), and only the
others are built and checked by the devkit's own `box_in_image`; the result is the same list of boxes, the same
numbers.
"""

from __future__ import annotations

import numpy as np
from pyquaternion import Quaternion

from nuparquet import geometry
from nuparquet.devkit.utils.data_classes import Box
from nuparquet.devkit.utils.geometry_utils import BoxVisibility, box_in_image
from nuparquet.geometry import quaternions

DEPTH_MARGIN_M = 1e-6  # the batch geometry's corners are within ~1e-10 m of the devkit's
PIXEL_MARGIN_PX = 1e-3
CORNER_MIN_DEPTH_M = 1.0  # devkit box_in_image: a visible corner is deeper than 1 m
BOX_MIN_DEPTH_M = 0.1  # ... and every corner of a kept box deeper than 0.1 m


class GlobalBoxes:
    """The boxes of one frame in the global frame, before they become `Box` objects.

    `records` are the annotations (dicts), `centers` (K, 3), `rotations` (K, 4) the interpolated values (or the
    annotation's), `interpolated[k]` says which; `previous[k]` the previous sample's annotation interpolated from.
    """

    def __init__(self, records: list[dict], centers: np.ndarray, rotations: np.ndarray, interpolated: np.ndarray,
                 previous: list[dict | None], amount):
        self.records = records
        self.centers = centers
        self.rotations = rotations
        self.interpolated = interpolated
        self.previous = previous
        self.amount = amount

    def __len__(self) -> int:
        return len(self.records)

    def box(self, k: int) -> Box:
        """Box k as the devkit's `get_box` (annotation) or `get_boxes` (interpolated) makes it."""
        record = self.records[k]
        if self.interpolated[k]:
            rotation = Quaternion.slerp(q0=Quaternion(self.previous[k]["rotation"]), q1=Quaternion(record["rotation"]),
                                        amount=self.amount)
            return Box._of(np.array(self.centers[k]), np.array(record["size"]), rotation, record["category_name"],
                           record["token"])
        return Box._of(np.array(record["translation"]), np.array(record["size"]), Quaternion(record["rotation"]),
                       record["category_name"], record["token"])

    def sizes(self) -> np.ndarray:
        return np.array([record["size"] for record in self.records], dtype=np.float64).reshape(-1, 3)


def global_boxes(nusc, sample_data_token: str) -> GlobalBoxes:
    """The boxes `get_boxes(sample_data_token)` returns, as values (see the module docstring)."""
    sd_record = nusc.get("sample_data", sample_data_token)
    current = nusc.get("sample", sd_record["sample_token"])
    records = [nusc.get("sample_annotation", token) for token in current["anns"]]
    k = len(records)
    translations = np.array([r["translation"] for r in records], dtype=np.float64).reshape(k, 3)
    rotations = np.array([r["rotation"] for r in records], dtype=np.float64).reshape(k, 4)
    interpolated = np.zeros(k, dtype=bool)
    previous: list[dict | None] = [None] * k
    if current["prev"] == "" or sd_record["is_key_frame"]:
        return GlobalBoxes(records, translations, rotations, interpolated, previous, None)

    prev_sample = nusc.get("sample", current["prev"])
    by_instance = {r["instance_token"]: r for r in (nusc.get("sample_annotation", t) for t in prev_sample["anns"])}
    for i, record in enumerate(records):
        previous[i] = by_instance.get(record["instance_token"])
        interpolated[i] = previous[i] is not None
    if not interpolated.any():
        return GlobalBoxes(records, translations, rotations, interpolated, previous, None)

    t0, t1 = prev_sample["timestamp"], current["timestamp"]
    t = max(t0, min(t1, sd_record["timestamp"]))  # timestamps slightly off in the database: clamp, as the devkit
    if t1 == t0:
        raise ZeroDivisionError(
            f"samples {prev_sample['token']} and {current['token']} have the same timestamp {t0}: the devkit's "
            f"get_boxes divides by their difference for sample_data {sample_data_token} (and fails the same way); "
            "nuparquet.frames.boxes.frame_boxes interpolates such frames with amount 1")
    rows = np.flatnonzero(interpolated)
    previous_translations = np.array([previous[i]["translation"] for i in rows], dtype=np.float64)
    n = len(rows)
    centers = translations.copy()
    centers[rows] = geometry.interp_two_points(np.full(n, t, dtype=np.float64), np.full(n, t0, dtype=np.float64),
                                               np.full(n, t1, dtype=np.float64), previous_translations,
                                               translations[rows])
    amount = (t - t0) / (t1 - t0)
    previous_rotations = np.array([previous[i]["rotation"] for i in rows], dtype=np.float64)
    rotations = rotations.copy()
    rotations[rows] = quaternions.quaternion_slerp(previous_rotations, rotations[rows], amount)  # for the pre-check
    return GlobalBoxes(records, centers, rotations, interpolated, previous, amount)


def get_boxes(nusc, sample_data_token: str) -> list[Box]:
    """The devkit's `NuScenes.get_boxes`: the frame's boxes in the global frame (interpolated for sweeps)."""
    boxes = global_boxes(nusc, sample_data_token)
    return [boxes.box(k) for k in range(len(boxes))]


class SensorMove:
    """The moves `get_sample_data` applies to every box: global -> ego (the frame's pose) -> sensor, or global ->
    flat ego (the pose's yaw only), with the devkit's quaternions, precomputed once per call."""

    def __init__(self, pose_record: dict, cs_record: dict, flat: bool):
        if flat:
            yaw = Quaternion(pose_record["rotation"]).yaw_pitch_roll[0]
            steps = [(pose_record["translation"], Quaternion(scalar=np.cos(yaw / 2), vector=[0, 0, np.sin(yaw / 2)]))]
        else:
            steps = [(pose_record["translation"], Quaternion(pose_record["rotation"])),
                     (cs_record["translation"], Quaternion(cs_record["rotation"]))]
        self.steps = []
        for translation, rotation in steps:
            inverse = rotation.inverse
            rotation_matrix = inverse.rotation_matrix  # normalises `inverse` in place, as Box.rotate does first
            self.steps.append((-np.array(translation), rotation_matrix, inverse._q_matrix()))
        # the same transforms for the batch pre-check: X_from_global
        X_from_global = np.eye(4)
        for translation, rotation_matrix, _ in self.steps:
            step = np.eye(4)
            step[:3, :3] = rotation_matrix
            step[:3, 3] = rotation_matrix @ translation
            X_from_global = step @ X_from_global
        self.X_from_global = X_from_global

    def apply(self, box: Box) -> Box:
        """`box.translate(-t); box.rotate(q.inverse)` per step, with the devkit's arithmetic (its velocity is NaN
        and stays NaN)."""
        center = box.center
        q = box.orientation.q
        for translation, rotation_matrix, q_matrix in self.steps:
            center += translation  # in place, as Box.translate
            center = np.dot(rotation_matrix, center)
            q = np.dot(q_matrix, q)
        box.center = center
        box.orientation = Quaternion(array=q)
        return box


def visibility_bounds(boxes: GlobalBoxes, move: SensorMove, intrinsic: np.ndarray, imsize,
                      vis_level) -> tuple[np.ndarray, np.ndarray]:
    """(maybe, surely): (K,) bool masks of the boxes that may pass the devkit's `box_in_image` (the others certainly
    do not) and of those that certainly do, by nuparquet's batch geometry with a margin on every comparison. Only
    the boxes in `maybe` and not in `surely` need the devkit's own test."""
    k = len(boxes)
    if vis_level == BoxVisibility.NONE or not k:
        return np.ones(k, dtype=bool), np.ones(k, dtype=bool)
    X_from_global = move.X_from_global
    centers = geometry.transform_points(X_from_global, boxes.centers)
    rotations = X_from_global[:3, :3] @ quaternions.rotation_matrices(boxes.rotations)
    corners = geometry.box_corners(centers, boxes.sizes(), rotations)  # (K, 8, 3)
    depth = corners[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = geometry.view_points(corners, intrinsic, normalize=True)[..., :2]
    width, height = imsize

    def corners_visible(px: float, m: float) -> np.ndarray:  # (K, 8): box_in_image's corner test, moved by a margin
        return ((uv[..., 0] > -px) & (uv[..., 0] < width + px) & (uv[..., 1] > -px) & (uv[..., 1] < height + px)
                & (depth > CORNER_MIN_DEPTH_M - m))

    bounds = []
    for px, m in ((PIXEL_MARGIN_PX, DEPTH_MARGIN_M), (-PIXEL_MARGIN_PX, -DEPTH_MARGIN_M)):
        visible = corners_visible(px, m)
        in_front = np.all(depth > BOX_MIN_DEPTH_M - m, axis=1)
        if vis_level == BoxVisibility.ALL:
            bounds.append(np.all(visible, axis=1) & in_front)
        elif vis_level == BoxVisibility.ANY:
            bounds.append(np.any(visible, axis=1) & in_front)
        else:
            raise ValueError("vis_level: {} not valid".format(vis_level))
    return bounds[0], bounds[1]


def get_sample_data(nusc, sample_data_token: str, box_vis_level=BoxVisibility.ANY, selected_anntokens=None,
                    use_flat_vehicle_coordinates: bool = False, pose_record: dict | None = None, turn=None):
    """The devkit's `NuScenes.get_sample_data`: (data path, boxes in the sensor frame (or the flat ego frame), the
    camera intrinsic (3, 3) or None). For a camera, boxes failing `box_in_image(box_vis_level)` are left out.

    `pose_record`: the ego pose the boxes are moved with (default: the frame's own, nuScenes'); `turn(box)`: one
    more move of each box after that (truckscenes-devkit's flat frame turns every box about its own up axis), which
    the batch pre-check does not know: every camera box then goes through `box_in_image`."""
    sd_record = nusc.get("sample_data", sample_data_token)
    cs_record = nusc.get("calibrated_sensor", sd_record["calibrated_sensor_token"])
    sensor_record = nusc.get("sensor", cs_record["sensor_token"])
    if pose_record is None:
        pose_record = nusc.get("ego_pose", sd_record["ego_pose_token"])
    data_path = nusc.get_sample_data_path(sample_data_token)
    camera = sensor_record["modality"] == "camera"
    cam_intrinsic = np.array(cs_record["camera_intrinsic"]) if camera else None
    imsize = (sd_record["width"], sd_record["height"]) if camera else None
    move = SensorMove(pose_record, cs_record, use_flat_vehicle_coordinates)

    if selected_anntokens is not None:
        candidates = [nusc.get_box(token) for token in selected_anntokens]
        decided = [False] * len(candidates)
    else:
        boxes = global_boxes(nusc, sample_data_token)
        if camera and turn is None:
            maybe, surely = visibility_bounds(boxes, move, cam_intrinsic, imsize, box_vis_level)
        else:
            maybe, surely = np.ones(len(boxes), dtype=bool), np.full(len(boxes), not camera)
        candidates = [boxes.box(k) for k in np.flatnonzero(maybe).tolist()]
        decided = surely[maybe].tolist()

    box_list = []
    for box, passes in zip(candidates, decided):
        move.apply(box)
        if turn is not None:
            turn(box)
        if camera:
            if passes:
                box.orientation._normalise()  # what box_in_image's corners() does to the box it keeps
            elif not box_in_image(box, cam_intrinsic, imsize, vis_level=box_vis_level):
                continue
        box_list.append(box)
    return data_path, box_list, cam_intrinsic


def box_velocity(nusc, sample_annotation_token: str, max_time_diff: float = 1.5) -> np.ndarray:
    """(3,) global velocity [vx, vy, vz] m/s from the track's neighbours, as the devkit's `box_velocity`: the
    centred difference, else the one-sided one; NaN for a one-annotation track or neighbours too far apart in time
    (more than `max_time_diff` s, twice that for the centred difference)."""
    current = nusc.get("sample_annotation", sample_annotation_token)
    has_prev = current["prev"] != ""
    has_next = current["next"] != ""
    if not has_prev and not has_next:
        return np.array([np.nan, np.nan, np.nan])
    first = nusc.get("sample_annotation", current["prev"]) if has_prev else current
    last = nusc.get("sample_annotation", current["next"]) if has_next else current
    pos_diff = np.array(last["translation"]) - np.array(first["translation"])
    time_last = 1e-6 * nusc.get("sample", last["sample_token"])["timestamp"]
    time_first = 1e-6 * nusc.get("sample", first["sample_token"])["timestamp"]
    time_diff = time_last - time_first
    if has_next and has_prev:
        max_time_diff *= 2
    if time_diff > max_time_diff:
        return np.array([np.nan, np.nan, np.nan])
    return pos_diff / time_diff
