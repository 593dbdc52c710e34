"""Facts about a dataset's sensor channels, taken from the data (never from nuScenes' own channel list).

- The reference lidar: the keyframe sensor whose ego pose stands for "the ego vehicle at this sample" (the
  devkit uses LIDAR_TOP). `LIDAR_TOP` when present, else the first lidar channel by name.
- The camera layout of a mosaic: a front row and a back row, each ordered left to right as seen from the
  driver's seat (front row) or as labelled in the devkit's `render_scene` (back row: BACK_LEFT, BACK,
  BACK_RIGHT, not mirrored). Rows come from the channel names (FRONT / BACK) when every camera has one,
  else from the camera's yaw; the order within a row from the yaw, then the name.

nuScenes names appear here only as defaults and in docs.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

DEFAULT_REFERENCE_LIDAR = "LIDAR_TOP"  # nuScenes' reference sensor, preferred when a dataset has it
DEFAULT_CAMERA = "CAM_FRONT"  # the default single camera of `render`, when a dataset has it


def reference_lidar(channels: Sequence[str], modalities: Sequence[str]) -> str | None:
    """The reference lidar channel of a dataset given each sensor's channel and modality (None: no lidar)."""
    lidars = sorted({c for c, m in zip(channels, modalities) if m == "lidar"})
    if DEFAULT_REFERENCE_LIDAR in lidars:
        return DEFAULT_REFERENCE_LIDAR
    return lidars[0] if lidars else None


def default_camera(cameras: Sequence[str], layout: Sequence[Sequence[str]] | None = None) -> str | None:
    """CAM_FRONT when the dataset has it, else the first camera of the front row of `layout` (see
    `camera_layout`; without it, the first camera named)."""
    if DEFAULT_CAMERA in cameras:
        return DEFAULT_CAMERA
    if layout and layout[0]:
        return layout[0][0]
    return cameras[0] if cameras else None


def camera_yaw(rotation_wxyz):
    """(N,) heading in radians of each camera's optical axis (sensor +z) in the ego frame (x forward, y left):
    0 looks forward, +pi/2 to the left, -pi/2 to the right."""
    import numpy as np  # only here: `channels` is imported by the CLI's option definitions, which stay light

    from nuparquet.geometry import quaternions

    axis = quaternions.rotation_matrices(np.asarray(rotation_wxyz, dtype=np.float64))[..., :, 2]
    return np.arctan2(axis[..., 1], axis[..., 0])


def _word(name: str, word: str) -> bool:
    return re.search(rf"(^|[^A-Z]){word}([^A-Z]|$)", name.upper()) is not None


def camera_layout(cameras: Sequence[str], yaws_rad: Sequence[float] | None = None) -> tuple[tuple[str, ...], ...]:
    """The mosaic rows of a camera set: (front row, back row), each left to right; one row if there is no back
    camera. `yaws_rad` (one per camera, see `camera_yaw`) orders cameras within a row and decides the rows when
    the names do not say FRONT or BACK; without it, names alone decide (LEFT before plain before RIGHT).
    """
    cameras = list(cameras)
    yaw = dict(zip(cameras, yaws_rad)) if yaws_rad is not None else {}
    by_name = all(_word(c, "FRONT") != _word(c, "BACK") for c in cameras)
    if by_name or not yaw:
        front = [c for c in cameras if not _word(c, "BACK")]
        back = [c for c in cameras if _word(c, "BACK")]
    else:
        front = [c for c in cameras if abs(yaw[c]) <= math.pi / 2]
        back = [c for c in cameras if abs(yaw[c]) > math.pi / 2]

    def side(name: str) -> int:
        return 0 if _word(name, "LEFT") else 2 if _word(name, "RIGHT") else 1

    def front_key(name: str):  # left to right: decreasing yaw
        return (-yaw[name], name) if name in yaw else (side(name), name)

    def back_key(name: str):  # BACK_LEFT, BACK, BACK_RIGHT: increasing yaw in [0, 2 pi)
        return (yaw[name] % (2 * math.pi), name) if name in yaw else (side(name), name)

    rows = [tuple(sorted(front, key=front_key)), tuple(sorted(back, key=back_key))]
    return tuple(row for row in rows if row)


def channel_facts(channels: Sequence[str], modalities: Sequence[str],
                  camera_rotations_wxyz: dict[str, Sequence[float]] | None = None) -> dict:
    """The channel facts of a dataset, as `manifest.json` records them under "channels":
    {"reference_lidar": str | None, "cameras": [...], "camera_layout": [[front row], [back row]],
    "lidars": [...], "radars": [...]} (names sorted; the layout as `camera_layout`).

    Args:
        channels, modalities: one entry per sensor (the `sensor` table).
        camera_rotations_wxyz: each camera's ego_from_sensor rotation (one calibration per camera), used for
            the layout when the names do not say FRONT / BACK and to order cameras within a row.
    """
    by_modality: dict[str, list[str]] = {}
    for channel, modality in sorted(set(zip(channels, modalities))):
        by_modality.setdefault(modality, []).append(channel)
    cameras = by_modality.get("camera", [])
    rotations = camera_rotations_wxyz or {}
    yaws = None
    if cameras and all(c in rotations for c in cameras):
        yaws = camera_yaw([rotations[c] for c in cameras]).tolist()
    return {
        "reference_lidar": reference_lidar(channels, modalities),
        "cameras": cameras,
        "camera_layout": [list(row) for row in camera_layout(cameras, yaws)],
        "lidars": by_modality.get("lidar", []),
        "radars": by_modality.get("radar", []),
    }


def channels_of_dataset(ds) -> dict:
    """`channel_facts` of a converted output whose manifest predates the "channels" record: from `tables/sensor`
    and one camera calibration per channel in `tables/calibrated_sensor` (else from `frames`)."""
    import polars as pl

    if not {"tables/sensor", "tables/calibrated_sensor"} <= set(ds.datasets):
        present = (ds.scan("frames").select(pl.col("channel").cast(pl.String), pl.col("modality").cast(pl.String))
                   .unique().sort("channel").collect())
        return channel_facts(present["channel"].to_list(), present["modality"].to_list())
    # The sensor table names every channel with its modality; one calibration per channel gives its yaw.
    sensors = ds.scan("tables/sensor").select("token", "channel", "modality")
    calibrations = (ds.scan("tables/calibrated_sensor").select("sensor_token", "token", "rotation")
                    .join(sensors.select(pl.col("token").alias("sensor_token"), "channel"), on="sensor_token")
                    .sort("channel", "token").unique("channel", keep="first"))
    sensors_df, calibrations_df = pl.collect_all([sensors, calibrations])
    rotations = dict(zip(calibrations_df["channel"].to_list(), calibrations_df["rotation"].to_list()))
    return channel_facts(sensors_df["channel"].to_list(), sensors_df["modality"].to_list(), rotations)
