"""The generator's world model holds together as real data does: CAN bus yaw rates follow the ego poses, log names
carry their location's local time and UTC offset, parked rows do not overlap, speed profiles depend only on elapsed
time, a track drawn single has one annotation, and the rigid-body helpers agree with pyquaternion. Expectations come
from the written tables and pyquaternion/shapely, or from the real nuScenes logs' conventions, not from the
generator's internals."""

from __future__ import annotations

import datetime as dt
import json
import re

import numpy as np
import pytest
import shapely
from pyquaternion import Quaternion

from conftest import SYNTH_VERSION
from nuparquet.synth import road, synthesize, world
from nuparquet.synth.rigid import box_corners, quat_from_matrix, quat_to_matrix


def _tables(root, *names):
    return {name: json.loads((root / SYNTH_VERSION / f"{name}.json").read_text()) for name in names}


def _turning_dataset(tmp_path):
    """3 scenes x 10 samples, tables and CAN bus only (~0.1 s): two logs (boston-seaport, singapore-onenorth), one
    holding two scenes, roads that turn (yaw rates up to 0.3 rad/s). Written in the test itself rather than taken
    from a session fixture: mutation runs map a generator function to the tests it runs in, and a session fixture's
    generation runs in the first test that asks for it only."""
    return synthesize(tmp_path / "data", scenes=3, samples_per_scene=10, seed=4, version=SYNTH_VERSION)


# -- CAN bus ----------------------------------------------------------------------------------------------------

def test_can_bus_yaw_rates_follow_the_heading_of_the_ego_poses(tmp_path):
    """The IMU's and the pose message's rotation rate about z is the rate of change of the ego heading: here the
    central difference over +-0.1 s of the heading pyquaternion reads from the ego_pose table, interpolated at each
    message at least 0.1 s inside the poses. The IMU carries gyro noise (the generator's promise: CAN values agree with the poses 'within the
    noise'); an RMS within 0.015 rad/s (under 1 deg/s) allows it, the noise-free pose message agrees closer."""
    root = _turning_dataset(tmp_path)
    t = _tables(root, "scene", "sample", "sample_data", "ego_pose")
    scene_of_sample = {s["token"]: s["scene_token"] for s in t["sample"]}
    poses = {p["token"]: p for p in t["ego_pose"]}
    checked, fastest = 0, 0.0
    for scene in t["scene"]:
        if not (root / "can_bus" / f"{scene['name']}_ms_imu.json").is_file():
            continue  # the generator leaves the last scene without CAN bus data
        frames = sorted({(poses[sd["ego_pose_token"]]["timestamp"], tuple(poses[sd["ego_pose_token"]]["rotation"]))
                         for sd in t["sample_data"] if scene_of_sample[sd["sample_token"]] == scene["token"]})
        pose_s = np.array([f[0] for f in frames]) / 1e6
        heading = np.unwrap([Quaternion(f[1]).yaw_pitch_roll[0] for f in frames])
        for message, rms_limit in (("ms_imu", 0.015), ("pose", 0.002)):
            records = json.loads((root / "can_bus" / f"{scene['name']}_{message}.json").read_text())
            utime_s = np.array([r["utime"] for r in records]) / 1e6
            yaw_rate = np.array([r["rotation_rate"][2] for r in records])
            inside = (utime_s - 0.1 >= pose_s[0]) & (utime_s + 0.1 <= pose_s[-1])  # both ends of the difference
            utime_s, yaw_rate = utime_s[inside], yaw_rate[inside]
            expected = (np.interp(utime_s + 0.1, pose_s, heading) - np.interp(utime_s - 0.1, pose_s, heading)) / 0.2
            rms = float(np.sqrt(np.mean((yaw_rate - expected) ** 2)))
            assert rms <= rms_limit, (scene["name"], message, rms)
            checked += len(records)
            fastest = max(fastest, float(np.abs(expected).max()))
    assert checked > 400 and fastest > 0.2  # the scenes turn: the rates are not all near zero


# The real CAN bus files' field names, in the order they write them (sorted), as read from the nuScenes extract's
# scene-0523 and scene-0916 files (checked against them by the next test where ../shared is present): the devkit's
# NuScenesCanBus and nuparquet's reader take these names as they are, so a generator's key in another case would be
# another field (another column) for every reader.
REAL_FIELDS = {
    "pose": ["accel", "orientation", "pos", "rotation_rate", "utime", "vel"],
    "ms_imu": ["linear_accel", "q", "rotation_rate", "utime"],
    "steeranglefeedback": ["utime", "value"],
    "vehicle_monitor": ["available_distance", "battery_level", "brake", "brake_switch", "gear_position",
                        "left_signal", "rear_left_rpm", "rear_right_rpm", "right_signal", "steering",
                        "steering_speed", "throttle", "utime", "vehicle_speed", "yaw_rate"],
}


def test_real_can_bus_files_have_the_fields_the_generator_is_held_to(extract_root):
    for path in sorted((extract_root / "can_bus").glob("scene-*_*.json")):
        message = path.stem.split("_", 1)[1]
        if message in REAL_FIELDS:
            assert all(list(r) == REAL_FIELDS[message] for r in json.loads(path.read_text())), path.name


def test_can_bus_messages_have_the_real_files_field_names_in_their_order(tmp_path):
    """The module's promise: the real files' field names and key order, case included, in every message."""
    root = _turning_dataset(tmp_path)
    checked = 0
    for path in sorted((root / "can_bus").glob("scene-*_*.json")):
        message = path.stem.split("_", 1)[1]
        if message in REAL_FIELDS:
            records = json.loads(path.read_text())
            assert records and all(list(r) == REAL_FIELDS[message] for r in records), path.name
            checked += 1
    assert checked == 2 * len(REAL_FIELDS)  # two scenes of three have CAN bus data


def test_the_accelerator_pedal_is_released_while_the_car_slows_down(tmp_path):
    """zoe_veh_info's pedal_cc (accelerator pedal position) and the drive torques follow the car's longitudinal
    acceleration, as in a real car: released (0) in every message where the car slows down (longitudinal_accel < 0),
    pressed in some where it speeds up; regenerative braking (regen) only while it slows down."""
    root = _turning_dataset(tmp_path)
    slowing = speeding = 0
    for path in sorted((root / "can_bus").glob("scene-*_zoe_veh_info.json")):
        for r in json.loads(path.read_text()):
            if r["longitudinal_accel"] < 0:
                slowing += 1
                assert r["pedal_cc"] == 0 and r["meanEffTorque"] == 0 and r["requestedTorqueAfterProc"] == 0, r
            else:
                assert r["regen"] == 0, r
                speeding += r["pedal_cc"] > 0
    assert slowing > 100 and speeding > 100


# -- logs -------------------------------------------------------------------------------------------------------

# The locations' UTC offsets, as the real nuScenes log names write them (n008-2018-08-30-10-33-52-0400 in
# boston-seaport, n015-2018-10-08-15-36-50+0800 in singapore-queenstown). Boston's -4 is daylight saving time,
# which in 2018 ran from 11 March to 4 November.
UTC_OFFSET_H = {"boston-seaport": -4, "singapore-onenorth": 8, "singapore-queenstown": 8,
                "singapore-hollandvillage": 8}
BOSTON_DST_2018 = (dt.date(2018, 3, 11), dt.date(2018, 11, 4))
LOGFILE = re.compile(r"(n\d{3})-(\d{4})-(\d\d)-(\d\d)-(\d\d)-(\d\d)-(\d\d)([+-])(\d\d)(\d\d)")


def test_log_names_carry_the_local_start_time_and_utc_offset_of_their_location(tmp_path):
    """Each logfile is '<vehicle>-<local date and time>±HHMM' with its location's UTC offset and sign (west of
    Greenwich: '-'); the local time it names, taken back to UTC with that offset, is when the log starts: before
    the first sample of its scenes and well within the hour (the real logs start 23 s and 84 s before theirs)."""
    t = _tables(_turning_dataset(tmp_path), "log", "scene", "sample")
    first_sample_us = {s["token"]: s["timestamp"] for s in t["sample"]}
    offsets = []
    for log in t["log"]:
        match = LOGFILE.fullmatch(log["logfile"])
        assert match, log["logfile"]
        vehicle, year, month, day, hour, minute, second, sign, off_h, off_m = match.groups()
        offset_h = (1 if sign == "+" else -1) * int(off_h)
        assert (offset_h, off_m) == (UTC_OFFSET_H[log["location"]], "00"), log
        assert vehicle == log["vehicle"] and f"{year}-{month}-{day}" == log["date_captured"], log
        if log["location"] == "boston-seaport":
            assert BOSTON_DST_2018[0] <= dt.date.fromisoformat(log["date_captured"]) < BOSTON_DST_2018[1]
        local = dt.datetime(int(year), int(month), int(day), int(hour), int(minute), int(second),
                            tzinfo=dt.timezone(dt.timedelta(hours=offset_h)))
        start_us = int(local.timestamp()) * 1_000_000
        scenes = [s for s in t["scene"] if s["log_token"] == log["token"]]
        assert scenes
        for scene in scenes:
            assert start_us <= first_sample_us[scene["first_sample_token"]], (log["logfile"], scene["name"])
        assert min(first_sample_us[s["first_sample_token"]] for s in scenes) - start_us < 3_600_000_000
        offsets.append(offset_h)
    assert len(t["scene"]) > len(t["log"])  # a log holds several scenes
    assert min(offsets) < 0 < max(offsets)  # both signs are written: a location west of Greenwich is in the set


# -- objects ----------------------------------------------------------------------------------------------------

def _footprints(s_m: np.ndarray, size_m: np.ndarray, yaw_rad: np.ndarray) -> list:
    """Bird's-eye polygons of boxes centred at (s, 0) on a straight road along x: length (size[:, 1]) along the
    box's heading, width (size[:, 0]) across it (the nuScenes wlh convention)."""
    polygons = []
    for s, (w, l, _), yaw in zip(s_m, size_m, yaw_rad):
        c, si = np.cos(yaw), np.sin(yaw)
        corners = [(s + c * dx - si * dy, si * dx + c * dy)
                   for dx, dy in ((l / 2, w / 2), (l / 2, -w / 2), (-l / 2, -w / 2), (-l / 2, w / 2))]
        polygons.append(shapely.Polygon(corners))
    return polygons


@pytest.mark.parametrize("row", world.ROWS, ids=lambda r: r.name)
def test_objects_of_a_row_do_not_overlap_seen_from_above(row):
    """A row's objects stand one after the other along it without touching (the module's promise: neighbours do
    not overlap), at the densest a scene draws (busy and row factors at their 1.4 maxima), whatever their headings
    (parked cars along the row, barriers and curb bicycles across it, cones at any angle); on any stretch, even
    one shorter than the objects, every object stands within it."""
    density = world.DENSITY_SCALE * 1.4 * 1.4 / row.presence  # as _place_objects draws it, at its maximum
    placed = 0
    for seed in range(4):
        rng = np.random.default_rng([seed, 29])
        category, size, s_m, yaw_offset = world._place_row(rng, row, density, 100.0, 400.0)
        assert len(category) == len(size) == len(s_m) == len(yaw_offset)
        assert np.all(np.diff(s_m) > 0) and s_m.min() >= 100.0 and s_m.max() <= 400.0
        polygons = _footprints(s_m, size, yaw_offset)
        left, right = shapely.STRtree(polygons).query(polygons, predicate="intersects")
        touching = [(int(a), int(b)) for a, b in zip(left, right) if a < b]
        assert not touching, (row.name, seed, touching[:3], [world.CATEGORIES[category[a]].name for a, _ in touching[:3]])
        placed += len(s_m)
    assert placed > 4 * 300 * row.per_100m / 100  # the rows are full: the test saw dense rows
    for length_m in (0.0, 0.5, 1.0, 1.5, 2.0, 3.0):  # stretches shorter than one car
        _, _, s_m, _ = world._place_row(np.random.default_rng(3), row, density, 50.0, 50.0 + length_m)
        assert np.all((s_m >= 50.0) & (s_m <= 50.0 + length_m)), (row.name, length_m, s_m)


def test_every_annotation_lies_within_the_annotation_radius_of_the_ego_car_at_its_sample(tmp_path):
    """The module's promise: an object is annotated at the samples where it is within its annotation radius (at most
    ANNOTATION_RADIUS_M[1]) of the ego car. Measured on the written tables, in the ground plane, from the ego pose of
    the sample's LIDAR_TOP keyframe (taken at the sample's time); the scenes' cars move, so a sample's ego position
    is not the scene's first or last."""
    root = _turning_dataset(tmp_path)
    t = _tables(root, "sample", "sample_data", "ego_pose", "sample_annotation", "calibrated_sensor", "sensor")
    lidar = {s["token"] for s in t["sensor"] if s["channel"] == "LIDAR_TOP"}
    lidar_calibrations = {c["token"] for c in t["calibrated_sensor"] if c["sensor_token"] in lidar}
    poses = {p["token"]: p for p in t["ego_pose"]}
    ego_at = {sd["sample_token"]: np.array(poses[sd["ego_pose_token"]]["translation"][:2]) for sd in t["sample_data"]
              if sd["is_key_frame"] and sd["calibrated_sensor_token"] in lidar_calibrations}
    assert len(ego_at) == len(t["sample"])
    distance = np.array([np.linalg.norm(np.array(a["translation"][:2]) - ego_at[a["sample_token"]])
                         for a in t["sample_annotation"]])
    assert distance.size > 300 and distance.max() <= world.ANNOTATION_RADIUS_M[1] + 0.01, distance.max()
    first = [ego_at[s["token"]] for s in t["sample"] if s["prev"] == ""]
    last = [ego_at[s["token"]] for s in t["sample"] if s["next"] == ""]
    assert max(np.linalg.norm(a - b) for a, b in zip(first, last)) > 30.0  # a car drives tens of metres


class _Draws:
    """Stands in for the generator's rng in `_tracks`: hands out the given uniform draws in the order asked (cut
    or not, a cut track's new start, its new end, single or not), each broadcast to the number of objects."""

    def __init__(self, *draws: float):
        self.draws = list(draws)

    def random(self, n: int) -> np.ndarray:
        return np.full(n, self.draws.pop(0))


def test_a_track_drawn_single_is_one_annotation_long_whatever_its_length():
    """`_tracks` makes a few tracks single ('a few are single'): one drawn single keeps one annotation, its first
    in range, whether its run in range is 2 samples or 5; one drawn neither cut nor single keeps its whole first
    run; an object never in range has no track."""
    in_range = np.array([
        [1, 1, 0, 0, 0, 0],  # a run of 2 from sample 0
        [0, 1, 1, 0, 1, 1],  # a run of 2 from sample 1 (the later run is not its track)
        [0, 0, 1, 1, 1, 0],  # 3
        [1, 1, 1, 1, 1, 1],  # the whole scene
        [0, 0, 0, 0, 1, 0],  # already one sample long
        [0, 0, 0, 0, 0, 0],  # never in range
    ], dtype=bool)
    first = np.array([0, 1, 2, 0, 4, 0])
    run = np.array([2, 2, 3, 6, 1, 0])
    not_cut, single, not_single = 0.99, 0.0, 0.99
    start, end = world._tracks(_Draws(not_cut, 0.5, 0.5, single), in_range)
    assert start[run > 0].tolist() == first[run > 0].tolist()
    assert (end - start).tolist() == [1, 1, 1, 1, 1, 0]
    start, end = world._tracks(_Draws(not_cut, 0.5, 0.5, not_single), in_range)
    assert start[run > 0].tolist() == first[run > 0].tolist() and (end - start).tolist() == run.tolist()


# -- speed profiles ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("style", ["cruise", "urban", "stop_and_go", "waiting"])
def test_a_speed_profile_depends_only_on_the_time_since_the_grid_starts(style):
    """travel_profile draws a speed knot every 3 s from the grid's first time: the same draws on a grid shifted
    in time give the same speeds at the same elapsed times over the whole grid (not a flat tail once the
    knots run out), and the distance is measured from t = 0 of each grid."""
    elapsed_s = np.arange(0.0, 40.0, world.TIME_STEP_S)  # the generator's grid step
    for shift_s in (-0.54, -15.0, 7.0):
        speed, distance = road.travel_profile(np.random.default_rng(11), elapsed_s, style)
        shifted_speed, shifted_distance = road.travel_profile(np.random.default_rng(11), elapsed_s + shift_s, style)
        np.testing.assert_allclose(shifted_speed, speed, atol=1e-9, err_msg=f"shift {shift_s}")
        zero = np.interp(-shift_s, elapsed_s, distance)  # the distance travelled when the shifted clock reads 0
        np.testing.assert_allclose(shifted_distance, distance - zero, atol=1e-6)
        assert np.all(speed >= 0.0) and np.all(speed <= road.MAX_SPEED_MPS)


# -- rigid-body helpers -----------------------------------------------------------------------------------------

def test_quat_from_matrix_equals_pyquaternion_in_every_branch_and_at_diagonal_ties():
    """Random rotations (every branch of the trace/diagonal pivot), half turns, and rotations whose matrix has
    m11 == m22 (the tie between the y and z pivots; the camera mounting matrix of `plan` is one): the quaternion
    is pyquaternion's up to sign, unit, with w >= 0."""
    rng = np.random.default_rng(29)
    q = rng.normal(size=(400, 4))
    q[:100, 0] = 0.0  # half turns: trace -1
    q[100:200, 3] = q[100:200, 2] * np.where(rng.random(100) < 0.5, 1.0, -1.0)  # y = +-z: m11 == m22
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    matrices = quat_to_matrix(q)
    optical = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    ties = 0
    for m in [*matrices, optical]:
        ties += bool(m[1, 1] == m[2, 2] and np.trace(m) <= 0)
        ours = quat_from_matrix(m)
        reference = Quaternion(matrix=m, atol=1e-9).elements
        assert min(np.abs(ours - reference).max(), np.abs(ours + reference).max()) < 1e-12, m
        assert abs(np.linalg.norm(ours) - 1.0) < 1e-12 and ours[0] >= 0.0
        np.testing.assert_allclose(quat_to_matrix(ours), m, atol=1e-12)
    assert ties > 20


def test_box_corners_are_the_devkits_box_corners():
    """`box_corners` gives the devkit's `Box.corners()`, in its order, for boxes of every shape (sizes from 0.3 m
    cones to 18 m buses, wider than long, flat and tall) and random rotations."""
    from nuscenes.utils.data_classes import Box

    rng = np.random.default_rng(53)
    center = rng.uniform(-50, 50, (60, 3))
    wlh = rng.uniform(0.3, 18.0, (60, 3))
    q = rng.normal(size=(60, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    ours = box_corners(center, wlh, q)
    for c, size, rotation, corners in zip(center, wlh, q, ours):
        np.testing.assert_allclose(corners, Box(c, size, Quaternion(rotation)).corners().T, atol=1e-9)


def test_a_barrier_stands_along_its_row():
    """A barrier's long side is its width (nuScenes' barriers: about 2.5 m wide, 0.5 m long): the generator turns it
    a quarter turn so that it stands along the median, as real barriers line a road. Seen from above (shapely
    footprints on a road along x), every barrier reaches farther along the road than across it."""
    row = next(r for r in world.ROWS if "movable_object.barrier" in r.categories)
    checked = 0
    for seed in range(3):
        category, size, s_m, yaw_offset = world._place_row(np.random.default_rng([seed, 31]), row, 1.0, 0.0, 300.0)
        is_barrier = np.array([world.CATEGORIES[c].name == "movable_object.barrier" for c in category])
        assert (size[is_barrier, 0] > 2 * size[is_barrier, 1]).all()  # wide, short boxes
        for polygon in np.array(_footprints(s_m, size, yaw_offset), dtype=object)[is_barrier]:
            x0, y0, x1, y1 = polygon.bounds
            assert x1 - x0 > 2 * (y1 - y0), polygon
            checked += 1
    assert checked >= 20
