"""Samples aligned with CAN bus messages: as-of join and interpolation, vectorised over every sample.

For a sample at time t and a message type with messages at times u_0 < u_1 < ...:
- the as-of message is the last one with u_i <= t (none before the first message), `age_us` = t - u_i;
- a continuous signal (a float field, or a fixed-size list of floats) is interpolated linearly between that
  message and the next one (u_i <= t < u_{i+1}) when both exist and u_{i+1} - u_i <= MAX_INTERPOLATION_GAP_US;
  at t == u_i it is that message's value. Quaternion fields (`orientation` of pose, `q` of ms_imu: 4 floats)
  are interpolated by slerp with pyquaternion's semantics (`nuparquet.geometry.quaternions.quaternion_slerp`).
Integer, boolean and string fields (gear, signals, switches) are discrete: as-of only.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.geometry import quaternions
from nuparquet.columns import to_numpy, to_series

# Messages further apart than this are not interpolated between (the slowest nuScenes message, vehicle_monitor,
# comes at 2 Hz: 0.5 s; a gap over 1 s means messages are missing).
MAX_INTERPOLATION_GAP_US = 1_000_000
QUATERNION_FIELDS = ("orientation", "q")


def continuous_fields(messages: pl.DataFrame) -> list[str]:
    """Float fields and fixed-size float lists, except utime."""
    out = []
    for name, dtype in messages.schema.items():
        if name in ("scene_name", "utime"):
            continue
        if dtype in (pl.Float64, pl.Float32) or (isinstance(dtype, pl.Array) and dtype.inner in (pl.Float64, pl.Float32)):
            out.append(name)
    return out


def neighbours(samples: pl.DataFrame, messages: pl.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Row of the last message at or before each sample (-1: none) and of the first message after it (-1: none),
    within the sample's scene. `samples`: scene_name, timestamp; `messages`: scene_name, utime (sorted)."""
    rows = messages.select("scene_name", "utime").with_row_index("_row")
    keyed = samples.select("scene_name", "timestamp").with_row_index("_sample").sort("scene_name", "timestamp")
    before = keyed.join_asof(rows, left_on="timestamp", right_on="utime", by="scene_name", strategy="backward",
                             check_sortedness=False)
    after = keyed.join_asof(rows, left_on="timestamp", right_on="utime", by="scene_name", strategy="forward",
                            allow_exact_matches=False, check_sortedness=False)
    order = keyed["_sample"].to_numpy()
    prev_row, next_row = np.full(samples.height, -1), np.full(samples.height, -1)
    prev_row[order] = before["_row"].fill_null(-1).to_numpy()
    next_row[order] = after["_row"].fill_null(-1).to_numpy()
    return prev_row, next_row


def aligned(samples: pl.DataFrame, message: str, messages: pl.DataFrame) -> pl.DataFrame:
    """Three columns per sample: `<message>` (struct of the as-of message, null before the first),
    `<message>_age_us` and `<message>_interp` (struct of the interpolated continuous fields, null where not
    defined)."""
    prev_row, next_row = neighbours(samples, messages)
    has_prev = prev_row >= 0
    fields = [c for c in messages.columns if c != "scene_name"]
    if messages.is_empty():  # every file of this message type is an empty array: no sample has a message
        taken = messages.select(fields).clear(samples.height)
    else:
        taken = messages.select(fields)[np.where(has_prev, prev_row, 0)]
    asof = taken.select(pl.struct(fields).alias(message))
    asof = asof.with_columns(pl.when(pl.Series(has_prev)).then(pl.col(message)).alias(message))
    t = samples["timestamp"].to_numpy()
    u = messages["utime"].to_numpy() if messages.height else np.zeros(1, np.int64)  # read where has_prev only
    u_prev = np.where(has_prev, u[np.maximum(prev_row, 0)], 0)
    age = pl.Series(f"{message}_age_us", t - u_prev).to_frame().select(
        pl.when(pl.Series(has_prev)).then(pl.col(f"{message}_age_us")).alias(f"{message}_age_us"))
    columns = [asof, age]
    continuous = continuous_fields(messages)
    if continuous and messages.height:
        columns.append(_interpolated(message, messages, continuous, t, u, prev_row, next_row))
    return pl.concat(columns, how="horizontal")


def _interpolated(message: str, messages: pl.DataFrame, continuous: list[str], t: np.ndarray, u: np.ndarray,
                  prev_row: np.ndarray, next_row: np.ndarray) -> pl.DataFrame:
    has_prev, has_next = prev_row >= 0, next_row >= 0
    p, q = np.maximum(prev_row, 0), np.maximum(next_row, 0)
    exact = has_prev & (u[p] == t)
    between = has_prev & has_next & ~exact & (u[q] - u[p] <= MAX_INTERPOLATION_GAP_US)
    valid = exact | between
    with np.errstate(divide="ignore", invalid="ignore"):
        amount = np.where(between, (t - u[p]) / np.where(between, u[q] - u[p], 1).astype(np.float64), 0.0)
    series = []
    for name in continuous:
        dtype = messages.schema[name]
        if isinstance(dtype, pl.Array):
            width = dtype.size
            values = to_numpy(messages[name], (width,))
            a, b = values[p], values[q]
            if name in QUATERNION_FIELDS and width == 4:
                out = np.where(exact[:, None], a, quaternions.quaternion_slerp(a, np.where(between[:, None], b, a), amount))
            else:
                out = np.where(exact[:, None], a, a + amount[:, None] * (b - a))
            series.append(to_series(name, out, valid=valid))
        else:
            values = messages[name].cast(pl.Float64).to_numpy()
            a, b = values[p], values[q]
            out = np.where(exact, a, a + amount * (b - a))
            series.append(pl.Series(name, out).to_frame().select(pl.when(pl.Series(valid)).then(pl.col(name))).to_series())
    frame = pl.DataFrame(series)
    return frame.select(pl.when(pl.Series(valid)).then(pl.struct(continuous)).alias(f"{message}_interp"))
