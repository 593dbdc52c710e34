"""CAN bus expansion files for a synthetic scene, consistent with its ego poses, in the real layout.

`can_bus/<scene>_<message>.json` for pose (50 Hz), ms_imu (100 Hz), steeranglefeedback (100 Hz),
vehicle_monitor (2 Hz), zoe_veh_info (100 Hz), plus `<scene>_meta.json` and `<scene>_route.json`, with the real
files' field names, key order (sorted) and value styles (ints where the real files have ints). Like the real
data, messages start a few milliseconds after the scene's first sample, so the first sample has no message at
or before it. Values are functions of the ego trajectory (position, heading, speed, yaw rate), so CAN speed
and ego-pose speed agree within the noise.

With `wild=True` the files take the shapes real CAN bus data has beyond the regular ones (issue 27): every stream
starts after the scene's second keyframe (two samples precede every message); a `zoesensors` stream (brake, steering
and throttle sensors, the real files' ~1 kHz message, here at `WILD_RATES_HZ`); messages dropped (`WILD_GAPS_US`:
pose has a gap of exactly 1 s, steeranglefeedback one of 1 s + 1 µs, vehicle_monitor misses one message); and the
meta file as the real ones are: keys in mixed case that are not the file names (`SteerAngleFeedback`,
`ZoeSensors`), `var_stats` with `utime` statistics (integer min/max), an object for ZOE_VEH_INFO and, in scenes of
odd number, for VEHICLE_MONITOR (null in the others, as in the real extract).

A scene too short for two messages of every stream (vehicle_monitor's 2 Hz: under about 0.54 s of keyframes, so
one or two samples; twice that with `wild=True`, one of its messages being dropped) gets no CAN bus files, as a
scene the expansion does not cover.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from nuparquet.synth.rigid import quat_from_yaw

RATES_HZ = {"pose": 50.0, "ms_imu": 100.0, "steeranglefeedback": 100.0, "vehicle_monitor": 2.0, "zoe_veh_info": 100.0}
WHEELBASE_M = 2.588  # a Renault Zoe, nuScenes' Singapore and Boston car
STEERING_RATIO = 15.0
GRAVITY_MPS2 = 9.80665
WILD_RATES_HZ = {"zoesensors": 500.0}  # real files: ~958 Hz; halved to keep the test files small
# Gaps cut into the streams of the wild files (messages dropped): exactly this long, or None for one message missing.
WILD_GAPS_US = {"pose": 1_000_000, "steeranglefeedback": 1_000_001, "vehicle_monitor": None}
# The real meta files' keys, in their order: mixed case, not the file names.
# Messages start this many microseconds after the first sample and end this many before the last ([low, high)).
START_DELAY_US = (2_000, 15_000)
END_EARLY_US = (0, 20_000)
META_KEYS = {"ms_imu": "MS_IMU", "pose": "POSE", "steeranglefeedback": "SteerAngleFeedback",
             "vehicle_monitor": "VEHICLE_MONITOR", "zoe_veh_info": "ZOE_VEH_INFO", "zoesensors": "ZoeSensors"}


def _trajectory(times_us: np.ndarray, frame_times_us: np.ndarray, frame_xy: np.ndarray, frame_yaw: np.ndarray):
    """Position, heading, speed (m/s), yaw rate (rad/s) and longitudinal acceleration at `times_us`, interpolated
    from the ego poses of the scene's frames."""
    order = np.argsort(frame_times_us, kind="stable")
    t_f = frame_times_us[order].astype(np.float64) / 1e6
    keep = np.r_[True, np.diff(t_f) > 0]
    t_f, xy, yaw = t_f[keep], frame_xy[order][keep], np.unwrap(frame_yaw[order][keep])
    t = times_us.astype(np.float64) / 1e6
    x, y, heading = np.interp(t, t_f, xy[:, 0]), np.interp(t, t_f, xy[:, 1]), np.interp(t, t_f, yaw)
    dt = np.gradient(t_f)
    speed_f = np.hypot(np.gradient(xy[:, 0]), np.gradient(xy[:, 1])) / dt
    speed = np.interp(t, t_f, speed_f)
    yaw_rate = np.interp(t, t_f, np.gradient(yaw) / dt)
    accel = np.interp(t, t_f, np.gradient(speed_f) / dt)
    return x, y, heading, speed, yaw_rate, accel


def _var_stats(values: np.ndarray) -> dict:
    values = values.reshape(len(values), -1).astype(np.float64)
    diff = np.diff(values, axis=0) if len(values) > 1 else np.zeros((1, values.shape[1]))
    return {"max": float(values.max()), "max_diff": float(diff.max()), "mean": float(values.mean()),
            "mean_diff": float(diff.mean()), "min": float(values.min()), "min_diff": float(diff.min()),
            "std": float(values.std()), "std_diff": float(diff.std())}


def _record_stats(records: list[dict]) -> dict:
    """var_stats as the real meta files write them: per field (utime too, with integer min and max) in key order."""
    out = {}
    for key in records[0]:
        values = np.array([r[key] for r in records])
        out[key] = _var_stats(values)
        if key == "utime":
            out[key]["max"], out[key]["min"] = int(values.max()), int(values.min())
    return out


def yaw_of(rotation_wxyz: np.ndarray) -> np.ndarray:
    """Heading of each ego rotation (the generator keeps its own maths, independent of the library)."""
    w, x, y, z = rotation_wxyz.T
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _drop_messages(times: np.ndarray, gap_us: int | None) -> np.ndarray:
    """`times` without the messages of one gap a third of the way in: exactly `gap_us` long (the first message after
    it moved onto its end), or (None) one message missing."""
    k = len(times) // 3
    if gap_us is None:
        return np.delete(times, k + 1)
    end = times[k] + gap_us
    return np.r_[times[: k + 1], end, times[times > end]]


def write_scene_can_bus(dataroot: Path, scene_name: str, rng: np.random.Generator, sample_times_us: np.ndarray,
                        frame_times_us: np.ndarray, frame_translation_m: np.ndarray, frame_yaw: np.ndarray,
                        *, wild: bool = False) -> None:
    """Write every CAN bus file of one scene into `dataroot/can_bus/` (`wild`: the real files' other shapes, see the
    module's docstring)."""
    first_us = int(sample_times_us[min(1, len(sample_times_us) - 1)] if wild else sample_times_us[0])
    slowest_period_us = 1e6 / min(RATES_HZ.values())
    if int(sample_times_us[-1]) - first_us - START_DELAY_US[1] - END_EARLY_US[1] < slowest_period_us * (2 if wild else 1):
        return  # too short for two messages of every stream (see the module's docstring)
    folder = dataroot / "can_bus"
    folder.mkdir(exist_ok=True)
    start_us = first_us + int(rng.integers(*START_DELAY_US))
    end_us = int(sample_times_us[-1]) - int(rng.integers(*END_EARLY_US))
    messages: dict[str, list[dict]] = {}
    stats: dict[str, dict] = {}
    odd_scene = int(scene_name.rsplit("-", 1)[-1]) % 2 == 1
    for name, rate in (RATES_HZ | WILD_RATES_HZ if wild else RATES_HZ).items():
        period_us = 1e6 / rate
        n = int((end_us - start_us) // period_us) + 1
        times = start_us + np.round(np.arange(n) * period_us + rng.normal(0, period_us * 0.02, n)).astype(np.int64)
        if wild:  # no jitter before the start: every stream begins after the second keyframe
            times = np.maximum(times, start_us)
        times = np.maximum.accumulate(times + np.arange(n))  # strictly increasing
        if wild and name in WILD_GAPS_US:
            times = _drop_messages(times, WILD_GAPS_US[name])
            n = len(times)
        x, y, heading, speed, yaw_rate, accel = _trajectory(times, frame_times_us, frame_translation_m[:, :2], frame_yaw)
        noise = lambda scale, *shape: rng.normal(0, scale, (n, *shape))  # noqa: E731
        if name == "pose":
            q = quat_from_yaw(heading)
            records = [{"accel": [float(a), float(b), float(c)], "orientation": [float(w), 0.0, 0.0, float(z)],
                        "pos": [float(px), float(py), 0.0], "rotation_rate": [float(r0), float(r1), float(r2)],
                        "utime": int(u), "vel": [float(v), 0.0, 0.0]}
                       for a, b, c, (w, _, _, z), px, py, (r0, r1, r2), u, v in zip(
                           accel + noise(0.05), speed * yaw_rate + noise(0.05), GRAVITY_MPS2 + noise(0.05), q, x, y,
                           np.c_[noise(0.01), noise(0.01), yaw_rate], times, speed)]
            stats["POSE"] = {k: _var_stats(np.array([r[k] for r in records])) for k in ("accel", "orientation", "pos", "rotation_rate", "vel")}
        elif name == "ms_imu":
            q = quat_from_yaw(heading - np.pi / 2)
            records = [{"linear_accel": [float(a), float(b), float(c)], "q": [float(v) for v in qq],
                        "rotation_rate": [float(r0), float(r1), float(r2)], "utime": int(u)}
                       for a, b, c, qq, (r0, r1, r2), u in zip(
                           accel + noise(0.1), speed * yaw_rate + noise(0.1), GRAVITY_MPS2 + noise(0.1), q,
                           np.c_[noise(0.01), noise(0.01), yaw_rate + noise(0.005)], times)]
            stats["MS_IMU"] = {k: _var_stats(np.array([r[k] for r in records])) for k in ("linear_accel", "q", "rotation_rate")}
        elif name == "steeranglefeedback":
            curvature = yaw_rate / np.maximum(speed, 0.5)
            value = np.arctan(WHEELBASE_M * curvature) * STEERING_RATIO
            records = [{"utime": int(u), "value": float(v)} for u, v in zip(times, value + noise(0.002))]
            stats["SteerAngleFeedback"] = {"value": _var_stats(value)}
        elif name == "vehicle_monitor":
            steering_deg = np.rad2deg(np.arctan(WHEELBASE_M * yaw_rate / np.maximum(speed, 0.5)) * STEERING_RATIO)
            rpm = speed / (2 * np.pi * 0.31) * 60
            records = [{"available_distance": int(150 - k // 10), "battery_level": int(90 - k // 20), "brake": int(b),
                        "brake_switch": int(b > 0) + 1, "gear_position": 7, "left_signal": 0,
                        "rear_left_rpm": round(float(r), 4), "rear_right_rpm": round(float(r) * 1.01, 4),
                        "right_signal": 0, "steering": round(float(s), 1), "steering_speed": round(abs(float(ds)), 1),
                        "throttle": int(th), "utime": int(u), "vehicle_speed": round(float(v) * 3.6, 2),
                        "yaw_rate": round(float(np.rad2deg(w)), 1)}
                       for k, (b, r, s, ds, th, u, v, w) in enumerate(zip(
                           np.clip(-accel * 30, 0, 60).astype(int), rpm, steering_deg, np.gradient(steering_deg),
                           np.clip(accel * 40, 0, 100).astype(int), times, speed, yaw_rate))]
            stats["VEHICLE_MONITOR"] = None
        elif name == "zoesensors":  # raw pedal and steering sensor voltages
            records = [{"brake_sensor": float(b), "steering_sensor": float(s), "throttle_sensor": float(t), "utime": int(u)}
                       for b, s, t, u in zip(0.18 + np.clip(-accel, 0, None) * 0.02 + noise(0.001),
                                             0.1887 + yaw_rate * 0.01 + noise(0.0005),
                                             0.12 + np.clip(accel, 0, None) * 0.03 + noise(0.001), times)]
        else:  # zoe_veh_info: wheel speeds and pedal positions
            records = [{"FL_wheel_speed": float(v * 9.1), "FR_wheel_speed": float(v * 9.1 * 1.002),
                        "RL_wheel_speed": float(v * 9.05), "RR_wheel_speed": float(v * 9.05 * 1.001),
                        "left_solar": 0, "longitudinal_accel": float(a), "meanEffTorque": int(max(a, 0) * 40),
                        "odom": int(k * v * 0.01), "odom_speed": float(v), "pedal_cc": int(max(a, 0) * 80),
                        "regen": int(max(-a, 0) * 30), "requestedTorqueAfterProc": int(max(a, 0) * 45),
                        "right_solar": 0, "steer_corrected": float(s), "steer_offset_can": 0.0, "steer_raw": float(s),
                        "transversal_accel": float(t), "utime": int(u)}
                       for k, (v, a, s, t, u) in enumerate(zip(speed, accel + noise(0.05), np.rad2deg(yaw_rate) * 3,
                                                                 speed * yaw_rate + noise(0.05), times))]
            stats["ZOE_VEH_INFO"] = None
        messages[name] = records
    for name, records in messages.items():
        (folder / f"{scene_name}_{name}.json").write_text(json.dumps(records))
    meta = {}
    for name, key in META_KEYS.items():
        if name not in messages:
            continue
        utimes = [r["utime"] for r in messages[name]]
        span_s = (utimes[-1] - utimes[0]) / 1e6
        var_stats = stats.get(key)
        if wild:
            var_stats = None if key == "VEHICLE_MONITOR" and not odd_scene else _record_stats(messages[name])
        meta[key] = {"message_count": len(utimes), "message_freq": len(utimes) / span_s if span_s else 0.0,
                     "timespan": span_s, "var_stats": var_stats}
    (folder / f"{scene_name}_meta.json").write_text(json.dumps(meta, indent=0))
    route_times = np.arange(int(frame_times_us.min()), int(frame_times_us.max()), 200_000)
    rx, ry, *_ = _trajectory(route_times, frame_times_us, frame_translation_m[:, :2], np.zeros(len(frame_times_us)))
    (folder / f"{scene_name}_route.json").write_text(json.dumps([[float(a), float(b)] for a, b in zip(rx, ry)], indent=0))
