"""The moving world of one scene: a road, the ego car driving along it, and the annotated objects around it.

The road is a smooth centreline parametrised by arc length `s` (gentle curvature, a few turns). Every object
lives on a *row* parallel to it at a fixed lateral offset: traffic lanes (same direction and oncoming), a bike
lane, parking rows, a median with barriers and cones, sidewalks with walking pedestrians and curbs with
standing pedestrians, parked bicycles, racks. Objects of one row share the row's speed profile and keep their
spacing, so boxes do not run into each other. An object is annotated at the samples where it is within its
annotation radius of the ego car; its track is one contiguous run of samples (some shortened at random, some
single-annotation tracks), as instance tracks are in nuScenes.

Only the keyframe states are generated: between keyframes an object moves exactly as the devkit interpolates
(linear centre, slerp rotation), which is what the painted sweep images show.

Longer than our ~300-line norm on purpose: rows, speed profiles and annotation runs are one model of a
scene, read together; it is test data's generator, not a library surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.synth.rigid import quat_from_axis_angle, quat_from_yaw, quat_multiply
from nuparquet.synth.road import Road, make_road, travel_profile
from nuparquet.synth.taxonomy import ATTRIBUTE_INDEX, CATEGORIES, CATEGORY_INDEX
from nuparquet.synth.timeline import Timeline

TIME_STEP_S = 0.02
ANNOTATION_RADIUS_M = (38.0, 55.0)
# Scales every row's density; tuned so that 850 scenes x 40 samples give ~1.17M annotations (~34 per sample)
# like nuScenes v1.0-trainval.
DENSITY_SCALE = 1.33

_PEDESTRIANS = {"human.pedestrian.adult": 0.87, "human.pedestrian.child": 0.04,
                "human.pedestrian.construction_worker": 0.03, "human.pedestrian.police_officer": 0.01,
                "human.pedestrian.personal_mobility": 0.02, "human.pedestrian.stroller": 0.02,
                "human.pedestrian.wheelchair": 0.01}
_TRAFFIC = {"vehicle.car": 0.82, "vehicle.truck": 0.09, "vehicle.bus.rigid": 0.03, "vehicle.bus.bendy": 0.005,
            "vehicle.emergency.police": 0.02, "vehicle.emergency.ambulance": 0.005, "vehicle.motorcycle": 0.03}
_CURB = {"human.pedestrian.adult": 0.42, "human.pedestrian.child": 0.04, "vehicle.bicycle": 0.18,
         "static_object.bicycle_rack": 0.04, "vehicle.motorcycle": 0.08, "movable_object.pushable_pullable": 0.12,
         "movable_object.trafficcone": 0.07, "human.pedestrian.stroller": 0.02, "human.pedestrian.wheelchair": 0.01,
         "animal": 0.02}


@dataclass(frozen=True)
class Row:
    """A line of objects parallel to the road. `lateral_m` is for right-hand traffic (negative = right of the
    centreline); left-hand traffic locations mirror it. `direction` +1 moves with increasing s, -1 against it,
    0 static."""

    name: str
    lateral_m: float
    direction: int
    motion: str  # "traffic", "cycling", "walking" or "static"
    per_100m: float  # mean number of objects per 100 m of row
    presence: float  # probability that a scene has this row populated at all
    categories: dict[str, float]


ROWS: tuple[Row, ...] = (
    Row("lane_same", -3.5, +1, "traffic", 3.2, 1.0, _TRAFFIC),
    Row("lane_oncoming", +3.6, -1, "traffic", 3.2, 1.0, _TRAFFIC),
    Row("lane_oncoming_far", +7.1, -1, "traffic", 2.5, 0.6, _TRAFFIC),
    Row("bike_lane", -5.6, +1, "cycling", 1.6, 0.5, {"vehicle.bicycle": 0.75, "vehicle.motorcycle": 0.2,
                                                     "human.pedestrian.personal_mobility": 0.05}),
    Row("median", +1.8, 0, "static", 10.0, 0.35, {"movable_object.barrier": 0.75, "movable_object.trafficcone": 0.25}),
    Row("parking_right", -7.6, 0, "static", 7.0, 0.9, {
        "vehicle.car": 0.82, "vehicle.truck": 0.08, "vehicle.trailer": 0.03, "vehicle.construction": 0.03,
        "vehicle.emergency.police": 0.01, "movable_object.trafficcone": 0.02, "movable_object.debris": 0.01}),
    Row("parking_left", +10.6, 0, "static", 5.0, 0.7, {"vehicle.car": 0.9, "vehicle.truck": 0.1}),
    Row("sidewalk_right_with", -10.0, +1, "walking", 1.8, 0.9, _PEDESTRIANS),
    Row("sidewalk_right_against", -10.9, -1, "walking", 1.8, 0.9, _PEDESTRIANS),
    Row("sidewalk_left_with", +13.4, +1, "walking", 1.5, 0.8, _PEDESTRIANS),
    Row("sidewalk_left_against", +14.3, -1, "walking", 1.5, 0.8, _PEDESTRIANS),
    Row("curb_right", -12.2, 0, "static", 3.2, 0.9, _CURB),
    Row("curb_left", +15.5, 0, "static", 2.6, 0.8, _CURB),
)


@dataclass(frozen=True)
class SceneWorld:
    """Ego poses of every frame and the annotations of one scene.

    Annotations are ordered by instance, then time: a track is a contiguous block covering consecutive samples,
    so an annotation's prev/next is its neighbour in the block.
    """

    timeline: Timeline
    ego_translation_m: np.ndarray  # (M, 3) global_from_ego translation per frame
    ego_rotation: np.ndarray  # (M, 4) global_from_ego quaternion per frame
    instance_category: np.ndarray  # (I,) index into CATEGORIES
    instance_first_annotation: np.ndarray  # (I,) index into the annotation arrays
    instance_n_annotations: np.ndarray  # (I,)
    annotation_instance: np.ndarray  # (A,)
    annotation_sample: np.ndarray  # (A,) index of the sample
    annotation_translation_m: np.ndarray  # (A, 3) global box centre, rounded to mm like the real data
    annotation_size_m: np.ndarray  # (A, 3) [width, length, height], rounded to mm
    annotation_rotation: np.ndarray  # (A, 4) global_from_box quaternion (yaw only)
    annotation_attribute: np.ndarray  # (A,) index into ATTRIBUTES, -1 for none
    annotation_visibility: np.ndarray  # (A,) 1..4
    annotation_num_lidar_pts: np.ndarray  # (A,)
    annotation_num_radar_pts: np.ndarray  # (A,)
    description: str
    road: Road | None = None  # the scene's road (the map expansion is drawn along it)

    @property
    def annotation_has_prev(self) -> np.ndarray:
        """(A,) bool: the annotation's track has an annotation at the previous sample."""
        a = self.annotation_instance
        return np.r_[False, a[1:] == a[:-1]]

    @property
    def annotation_has_next(self) -> np.ndarray:
        a = self.annotation_instance
        return np.r_[a[:-1] == a[1:], False]


def _choose(rng: np.random.Generator, mixture: dict[str, float], n: int) -> np.ndarray:
    names = list(mixture)
    p = np.array([mixture[k] for k in names], dtype=np.float64)
    picks = rng.choice(len(names), size=n, p=p / p.sum())
    return np.array([CATEGORY_INDEX[names[i]] for i in range(len(names))])[picks]


def _yaw_offsets(rng: np.random.Generator, row: Row, category: np.ndarray) -> np.ndarray:
    """Heading of each object relative to the road tangent at its position."""
    names = [CATEGORIES[c].name for c in category]
    n = len(names)
    offset = rng.normal(0.0, 0.03, n)
    if row.direction < 0:
        offset += np.pi
    if row.motion == "static":
        for i, name in enumerate(names):
            if name == "movable_object.barrier":
                offset[i] += np.pi / 2  # a barrier's long side is its width: it stands along the road
            elif name in ("vehicle.bicycle", "vehicle.motorcycle") and row.name.startswith("curb"):
                offset[i] += np.pi / 2 + rng.normal(0.0, 0.2)  # parked perpendicular to the curb
            elif not name.startswith("vehicle.") and name != "static_object.bicycle_rack":
                offset[i] = rng.uniform(-np.pi, np.pi)  # cones, debris, standing pedestrians: any heading
            elif row.name == "parking_left" and rng.random() < 0.8:
                offset[i] += np.pi  # parked facing the traffic of its side
    return offset


def _place_row(rng: np.random.Generator, row: Row, density_scale: float, s_lo: float, s_hi: float):
    """Categories (N,), sizes (N, 3), arc-length positions (N,) and yaw offsets (N,) along [s_lo, s_hi], spaced
    so that neighbours do not overlap."""
    mean_gap_m = 100.0 / (row.per_100m * density_scale)
    n_max = int((s_hi - s_lo) / 0.5) + 2
    n_guess = min(n_max, int(1.5 * (s_hi - s_lo) / mean_gap_m) + 8)
    category = _choose(rng, row.categories, n_guess)
    mean_wlh = np.array([CATEGORIES[c].wlh_m for c in category]).reshape(-1, 3)
    size = np.round(mean_wlh * np.clip(rng.normal(1.0, 0.07, (n_guess, 3)), 0.8, 1.2), 3)
    yaw_offset = _yaw_offsets(rng, row, category)
    along_m = np.abs(np.cos(yaw_offset)) * size[:, 1] + np.abs(np.sin(yaw_offset)) * size[:, 0]
    gap = 0.5 * (along_m[1:] + along_m[:-1]) + 1.0 + rng.exponential(mean_gap_m, n_guess - 1)
    s = s_lo + rng.uniform(0.0, mean_gap_m) + np.r_[0.0, np.cumsum(gap)]
    keep = s <= s_hi
    return category[keep], size[keep], s[keep], yaw_offset[keep]


def _first_run(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(I, K) bool -> start (I,) and exclusive end (I,) of each row's first run of True (start == end: none)."""
    k = mask.shape[1]
    start = mask.argmax(axis=1)
    after_start_out = ~mask & (np.arange(k) >= start[:, None])
    end = np.where(after_start_out.any(axis=1), after_start_out.argmax(axis=1), k)
    end = np.where(mask.any(axis=1), end, start)
    return start, end


def _attributes(rng, category: np.ndarray, row_motion: np.ndarray, speed_mps: np.ndarray) -> np.ndarray:
    """(I,) categories and row motions, (I, K) object speeds -> (I, K) attribute index (-1: none)."""
    n, k = speed_mps.shape
    out = np.full((n, k), -1, dtype=np.int64)
    group = np.array([CATEGORIES[c].group for c in category])
    static = row_motion == "static"
    vehicle = group == "vehicle"
    out[vehicle & static] = ATTRIBUTE_INDEX["vehicle.parked"]
    moving_vehicle = vehicle & ~static
    out[moving_vehicle] = np.where(speed_mps[moving_vehicle] > 0.3, ATTRIBUTE_INDEX["vehicle.moving"],
                                   ATTRIBUTE_INDEX["vehicle.stopped"])
    cycle = group == "cycle"
    riderless = rng.random(n) < 0.9
    out[cycle & static & riderless] = ATTRIBUTE_INDEX["cycle.without_rider"]
    out[cycle & ~(static & riderless)] = ATTRIBUTE_INDEX["cycle.with_rider"]
    pedestrian = group == "pedestrian"
    sitting = rng.random(n) < 0.12
    out[pedestrian & ~static] = ATTRIBUTE_INDEX["pedestrian.moving"]
    out[pedestrian & static & sitting] = ATTRIBUTE_INDEX["pedestrian.sitting_lying_down"]
    out[pedestrian & static & ~sitting] = ATTRIBUTE_INDEX["pedestrian.standing"]
    return out


def _describe(style: str, turns: list[float], category: np.ndarray, rows_present: list[str]) -> str:
    words = {"cruise": "Cruising", "urban": "Slow urban driving", "stop_and_go": "Stop and go",
             "waiting": "Waiting, then pulling away"}[style].split(", ")
    words += ["left turn" if a > 0 else "right turn" for a in turns if abs(a) > 0.6]
    names = {CATEGORIES[c].name for c in category}
    for name, phrase in (("vehicle.bus.rigid", "bus"), ("vehicle.bus.bendy", "bendy bus"), ("vehicle.truck", "trucks"),
                         ("vehicle.construction", "construction vehicle"), ("vehicle.emergency.police", "police"),
                         ("vehicle.bicycle", "bicycles"), ("human.pedestrian.adult", "peds")):
        if name in names:
            words.append(phrase)
    if "median" in rows_present:
        words.append("barriers on the median")
    return ", ".join(words)


@dataclass(frozen=True)
class _Objects:
    """Every candidate object of a scene at the sample times, before the annotation radius is applied."""

    category: np.ndarray  # (N,) index into CATEGORIES
    size_m: np.ndarray  # (N, 3) [width, length, height]
    xy_m: np.ndarray  # (N, K, 2) global position
    yaw_rad: np.ndarray  # (N, K)
    speed_mps: np.ndarray  # (N, K)
    motion: np.ndarray  # (N,) str: the motion of the object's row
    radius_m: np.ndarray  # (N,) annotation radius around the ego car

    def __getitem__(self, keep: np.ndarray) -> _Objects:
        return _Objects(*(getattr(self, f)[keep] for f in self.__dataclass_fields__))


def _row_motions(rng, t_grid_s: np.ndarray, sample_t_s: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Speed [m/s] and distance travelled [m] of every row in ROWS at the sample times: (K,) arrays."""
    speeds, travels = [], []
    for row in ROWS:
        if row.motion in ("traffic", "cycling"):
            style = "stop_and_go" if rng.random() < 0.2 else ("cruise" if row.motion == "traffic" else "urban")
            speed, travel = travel_profile(rng, t_grid_s, style)
            if row.motion == "cycling":
                speed, travel = 0.6 * speed, 0.6 * travel
        elif row.motion == "walking":
            walk_mps = rng.uniform(1.1, 1.6)
            speed, travel = np.full_like(t_grid_s, walk_mps), walk_mps * t_grid_s
        else:
            speed, travel = np.zeros_like(t_grid_s), np.zeros_like(t_grid_s)
        speeds.append(np.interp(sample_t_s, t_grid_s, speed))
        travels.append(np.interp(sample_t_s, t_grid_s, travel))
    return speeds, travels


def _ego_poses(rng, road: Road, ego_s_m: np.ndarray, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M, 3) translations and (M, 4) rotations of global_from_ego: on the centreline of its lane, with the
    small pitch and roll of a real suspension, z = 0 like the real ego poses."""
    xy, heading = road.at(ego_s_m)
    pitch = np.deg2rad(0.25) * np.sin(2 * np.pi * t_s / rng.uniform(3, 9) + rng.uniform(0, 2 * np.pi))
    roll = np.deg2rad(0.15) * np.sin(2 * np.pi * t_s / rng.uniform(3, 9) + rng.uniform(0, 2 * np.pi))
    rotation = quat_multiply(quat_multiply(quat_from_yaw(heading), quat_from_axis_angle((0.0, 1.0, 0.0), pitch)),
                             quat_from_axis_angle((1.0, 0.0, 0.0), roll))
    return np.c_[xy, np.zeros(len(xy))], rotation


def _place_objects(rng, road: Road, row_speeds, row_travels, ego_lo_m: float, ego_hi_m: float,
                   drives_on_right: bool) -> tuple[_Objects, list[str]]:
    """Objects of every populated row over the stretch of road they can be seen from, and the rows' names."""
    side = 1.0 if drives_on_right else -1.0
    reach_m = ANNOTATION_RADIUS_M[1] + 5.0
    busy = rng.uniform(0.6, 1.4)
    parts, present = [], []
    for row, speed, travel in zip(ROWS, row_speeds, row_travels):
        if rng.random() >= row.presence:
            continue
        present.append(row.name)
        density = DENSITY_SCALE * busy * rng.uniform(0.6, 1.4) / row.presence  # absent rows are made up for
        lo = ego_lo_m - reach_m - (travel.max() if row.direction > 0 else 0.0)
        hi = ego_hi_m + reach_m + (travel.max() if row.direction < 0 else 0.0)
        category, size, s0_m, yaw_offset = _place_row(rng, row, density, lo, hi)
        jitter_m = rng.normal(0.0, 0.12, category.size) if row.motion == "static" else np.zeros(category.size)
        s_m = s0_m[:, None] + row.direction * travel[None, :]  # (N, K)
        xy, heading = road.at(s_m, side * (row.lateral_m + jitter_m)[:, None])
        parts.append(_Objects(category, size, xy, heading + yaw_offset[:, None], np.broadcast_to(speed, s_m.shape),
                              np.full(category.size, row.motion), rng.uniform(*ANNOTATION_RADIUS_M, category.size)))
    k = row_speeds[0].size
    if not parts:  # an empty road: no instances, no annotations
        parts.append(_Objects(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, k, 2)), np.zeros((0, k)),
                              np.zeros((0, k)), np.zeros(0, str), np.zeros(0)))
    return _Objects(*(np.concatenate([getattr(p, f) for p in parts]) for f in _Objects.__dataclass_fields__)), present


def _tracks(rng, in_range: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, K) in-range mask -> first sample (N,) and exclusive end (N,) of each object's track: its first run
    in range, then occlusion and annotator choices: some tracks start late or end early, a few are single."""
    start, end = _first_run(in_range)
    n = start.size
    length = end - start
    cut = (rng.random(n) < 0.12) & (length > 1)
    new_start = start + (rng.random(n) * length * 0.5).astype(int)
    new_end = new_start + 1 + (rng.random(n) * (end - new_start - 1)).astype(int)
    single = (rng.random(n) < 0.03) & (length > 1)
    start, end = np.where(cut, new_start, start), np.where(cut, new_end, end)
    return start, np.where(single, start + 1, end)


def _sensor_counts(rng, distance_m: np.ndarray, size_m: np.ndarray, is_vehicle: np.ndarray):
    """(A,) distances to the ego car, (A, 3) sizes, (A,) bool -> visibility level (1..4), num_lidar_pts and
    num_radar_pts: fewer with distance and lower visibility, 0 for many far boxes, as in the real data."""
    score = 1.0 - distance_m / 60.0 + rng.normal(0.0, 0.25, distance_m.size)
    visibility = 1 + np.digitize(score, [0.2, 0.4, 0.55])
    cross_section_m2 = np.maximum(size_m[:, 0], size_m[:, 1]) * size_m[:, 2]
    visible_fraction = np.array([0.0, 0.2, 0.5, 0.7, 1.0])[visibility]
    lam_lidar = 3000.0 * cross_section_m2 * visible_fraction / np.maximum(distance_m, 3.0) ** 2
    num_lidar = rng.poisson(np.minimum(lam_lidar, 4000.0))
    lam_radar = np.where(is_vehicle, 6.0, 0.4) * visible_fraction * np.clip(1.0 - distance_m / 70.0, 0.0, 1.0)
    return visibility.astype(np.int64), num_lidar.astype(np.int64), rng.poisson(lam_radar).astype(np.int64)


def build_scene(rng: np.random.Generator, timeline: Timeline, drives_on_right: bool) -> SceneWorld:
    """Ego poses for every frame of the timeline and the annotations of every sample."""
    sample_t_s = (timeline.sample_timestamp_us - timeline.sample_timestamp_us[0]) / 1e6  # (K,)
    frame_t_s = (timeline.frame_timestamp_us - timeline.sample_timestamp_us[0]) / 1e6  # (M,)
    t_grid_s = np.arange(min(frame_t_s.min(), 0.0) - 0.5, max(frame_t_s.max(), 1.0) + 0.5, TIME_STEP_S)

    style = str(rng.choice(["cruise", "urban", "stop_and_go", "waiting"], p=[0.4, 0.3, 0.18, 0.12]))
    _, ego_travel_m = travel_profile(rng, t_grid_s, style)
    ego_s_frame = np.interp(frame_t_s, t_grid_s, ego_travel_m)  # (M,)
    ego_s_sample = np.interp(sample_t_s, t_grid_s, ego_travel_m)  # (K,)
    row_speeds, row_travels = _row_motions(rng, t_grid_s, sample_t_s)

    # The road must reach as far as any object that comes within annotation range during the scene.
    max_travel_m = max(float(np.abs(t).max()) for t in row_travels)
    ego_lo, ego_hi = float(ego_s_frame.min()), float(ego_s_frame.max())
    margin_m = ANNOTATION_RADIUS_M[1] + max_travel_m + 60.0
    road, turns = make_road(rng, ego_lo - margin_m, ego_hi + margin_m, ego_hi)
    ego_translation, ego_rotation = _ego_poses(rng, road, ego_s_frame, frame_t_s)

    objects, present = _place_objects(rng, road, row_speeds, row_travels, ego_lo, ego_hi, drives_on_right)
    ego_xy_sample, _ = road.at(ego_s_sample)  # (K, 2)
    distance = np.linalg.norm(objects.xy_m - ego_xy_sample[None], axis=-1)  # (N, K)
    start, end = _tracks(rng, distance <= objects.radius_m[:, None])
    keep = end > start
    objects, distance, start, end = objects[keep], distance[keep], start[keep], end[keep]

    n_ann = end - start
    first = np.r_[0, np.cumsum(n_ann)[:-1]].astype(np.int64)
    ann_instance = np.repeat(np.arange(objects.category.size), n_ann)
    ann_sample = np.arange(n_ann.sum()) - np.repeat(first, n_ann) + np.repeat(start, n_ann)
    attribute = _attributes(rng, objects.category, objects.motion, objects.speed_mps)[ann_instance, ann_sample]
    ann_size = objects.size_m[ann_instance]
    ann_z = 0.5 * ann_size[:, 2] + rng.normal(0.0, 0.02, ann_instance.size)  # box centre above flat ground
    ann_translation = np.round(np.c_[objects.xy_m[ann_instance, ann_sample], ann_z], 3)  # mm, like the real data
    ann_yaw = (objects.yaw_rad[ann_instance, ann_sample] + np.pi) % (2 * np.pi) - np.pi
    is_vehicle = np.array([CATEGORIES[c].group in ("vehicle", "cycle") for c in objects.category], dtype=bool)
    visibility, num_lidar, num_radar = _sensor_counts(rng, distance[ann_instance, ann_sample], ann_size,
                                                      is_vehicle[ann_instance])
    return SceneWorld(
        timeline=timeline,
        ego_translation_m=ego_translation,
        ego_rotation=ego_rotation,
        instance_category=objects.category,
        instance_first_annotation=first,
        instance_n_annotations=n_ann.astype(np.int64),
        annotation_instance=ann_instance,
        annotation_sample=ann_sample.astype(np.int64),
        annotation_translation_m=ann_translation,
        annotation_size_m=ann_size,
        annotation_rotation=quat_from_yaw(ann_yaw),
        annotation_attribute=attribute,
        annotation_visibility=visibility,
        annotation_num_lidar_pts=num_lidar,
        annotation_num_radar_pts=num_radar,
        description=_describe(style, turns, objects.category, present),
        road=road,
    )
