"""What the index reads from a converted directory: the source tables (for the converter's orders: samples
in `sample.json` order, annotations in `sample['anns']` order) and the `annotations` dataset (its velocity is
the devkit's `box_velocity`), as flat numpy arrays. Checks that every needed dataset is there first."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from nuparquet.columns import to_numpy
from nuparquet.dataset import Dataset
from nuparquet.errors import InputError

NEEDED = ("tables/sample", "tables/sample_data", "tables/calibrated_sensor", "tables/ego_pose", "tables/sensor",
          "tables/scene", "tables/sample_annotation", "annotations")


def check_inputs(ds: Dataset, extra: tuple[str, ...] = ()) -> None:
    missing = [name for name in NEEDED + extra if name not in ds.datasets]
    if missing:
        raise InputError(f"{ds.root} lacks {', '.join(missing)}, which the training index needs: convert the "
                         "dataset again with `nuparquet convert` (with its annotations"
                         + (" and CAN bus data" if any("can_bus" in m for m in missing) else "") + ")")


@dataclass
class SampleData:
    """The sample_data rows the infos use, in table order: every reading of the lidar, the cameras' keyframes."""

    token: np.ndarray  # (D,) str
    channel: np.ndarray  # (D,) str
    is_key_frame: np.ndarray  # (D,) bool
    prev: np.ndarray  # (D,) int64 row of the prev reading, -1 at a chain start
    filename: np.ndarray  # (D,) str, relative to the dataroot
    timestamp_us: np.ndarray  # (D,) int64
    sensor_t: np.ndarray  # (D, 3) calibrated_sensor translation
    sensor_q: np.ndarray  # (D, 4) calibrated_sensor rotation [w, x, y, z]
    intrinsic: np.ndarray  # (D, 3, 3) NaN for non-cameras
    ego_t: np.ndarray  # (D, 3)
    ego_q: np.ndarray  # (D, 4)


@dataclass
class Inputs:
    sample_token: np.ndarray  # (S,) str, sample.json order
    sample_scene: np.ndarray  # (S,) str scene_token
    sample_timestamp_us: np.ndarray  # (S,) int64
    scene_token: np.ndarray  # (C,) str
    scene_name: np.ndarray  # (C,) str
    data: SampleData
    keyframe: dict[str, np.ndarray]  # channel -> (S,) row into `data` of the sample's keyframe, -1 if none
    ann_sample: np.ndarray  # (A,) int64 sample row, annotations in sample_annotation.json order
    ann_token: np.ndarray
    ann_center: np.ndarray  # (A, 3) global
    ann_size_wlh: np.ndarray  # (A, 3)
    ann_rotation: np.ndarray  # (A, 4)
    ann_velocity: np.ndarray  # (A, 3) global, NaN where the devkit gives NaN
    ann_category: np.ndarray  # (A,) str
    ann_attribute: np.ndarray  # (A,) str: the first attribute's name, "None" without one
    ann_visibility: np.ndarray  # (A,) str visibility token
    ann_num_lidar_pts: np.ndarray  # (A,) int64
    ann_num_radar_pts: np.ndarray  # (A,) int64


def _rows(tokens: pl.Series, keys: pl.Series) -> np.ndarray:
    """Row of each key in `tokens` (-1 for "" or unknown)."""
    lookup = pl.DataFrame({"_k": tokens, "_row": np.arange(len(tokens), dtype=np.int64)})
    return (pl.DataFrame({"_k": keys}).join(lookup, on="_k", how="left", maintain_order="left")["_row"]
            .fill_null(-1).to_numpy())


def read_inputs(ds: Dataset, cameras: tuple[str, ...], lidar: str) -> Inputs:
    """The inputs for `cameras` and `lidar`. Of sample_data, only the rows the infos can use are read: every
    `lidar` reading (sweeps follow its prev chain) and the keyframes of the cameras; camera sweeps and radar,
    most of the table, never are."""
    check_inputs(ds)
    sample = ds.scan("tables/sample").select("token", "timestamp", "scene_token").collect()
    scene = ds.scan("tables/scene").select("token", "name").collect()
    calib = (ds.scan("tables/calibrated_sensor")
             .join(ds.scan("tables/sensor").select(pl.col("token").alias("sensor_token"), "channel"),
                   on="sensor_token", how="left")
             .select(pl.col("token").alias("calibrated_sensor_token"), "channel", pl.col("translation").alias("s_t"),
                     pl.col("rotation").alias("s_q"), "camera_intrinsic")
             .collect())
    # filters on tokens rather than on joined columns: polars applies them while it reads
    lidar_calib = calib.filter(pl.col("channel") == lidar)["calibrated_sensor_token"]
    camera_calib = calib.filter(pl.col("channel").is_in(list(cameras)))["calibrated_sensor_token"]
    sd = (ds.scan("tables/sample_data")
          .select("token", "sample_token", "ego_pose_token", "calibrated_sensor_token", "timestamp", "is_key_frame",
                  "filename", "prev")
          .filter(pl.col("calibrated_sensor_token").is_in(lidar_calib.implode())
                  | (pl.col("is_key_frame") & pl.col("calibrated_sensor_token").is_in(camera_calib.implode())))
          .collect()
          .join(calib, on="calibrated_sensor_token", how="left", maintain_order="left"))
    pose = (ds.scan("tables/ego_pose").filter(pl.col("token").is_in(sd["ego_pose_token"].implode()))
            .select(pl.col("token").alias("ego_pose_token"), pl.col("translation").alias("e_t"),
                    pl.col("rotation").alias("e_q"))
            .collect())
    sd = sd.join(pose, on="ego_pose_token", how="left", maintain_order="left")
    data = SampleData(
        token=sd["token"].to_numpy(), channel=sd["channel"].to_numpy(), is_key_frame=sd["is_key_frame"].to_numpy(),
        prev=_rows(sd["token"], sd["prev"]), filename=sd["filename"].to_numpy(),
        timestamp_us=sd["timestamp"].to_numpy(), sensor_t=to_numpy(sd["s_t"], (3,)),
        sensor_q=to_numpy(sd["s_q"], (4,)), intrinsic=to_numpy(sd["camera_intrinsic"], (3, 3)),
        ego_t=to_numpy(sd["e_t"], (3,)), ego_q=to_numpy(sd["e_q"], (4,)))

    # The devkit's sample['data'][channel]: the keyframe reading of that channel (the last in table order).
    sd_sample = _rows(sample["token"], sd["sample_token"])
    keyframe = {}
    for channel in (*cameras, lidar):
        pick = np.flatnonzero(data.is_key_frame & (data.channel == channel) & (sd_sample >= 0))
        rows = np.full(len(sample), -1, dtype=np.int64)
        rows[sd_sample[pick]] = pick
        keyframe[channel] = rows

    sa = ds.scan("tables/sample_annotation").select("token", "sample_token", "visibility_token",
                                                    "num_lidar_pts", "num_radar_pts").collect()
    ann = ds.scan("annotations").select("token", "translation", "size", "rotation", "velocity", "category_name",
                                        pl.col("attribute_names").list.first().fill_null("None").alias("attr"))
    ann = sa.join(ann.collect(), on="token", how="left", maintain_order="left")
    if ann["translation"].null_count():
        raise InputError(f"{ds.root}: the annotations dataset does not match tables/sample_annotation; convert again")
    return Inputs(
        sample_token=sample["token"].to_numpy(), sample_scene=sample["scene_token"].to_numpy(),
        sample_timestamp_us=sample["timestamp"].to_numpy(),
        scene_token=scene["token"].to_numpy(), scene_name=scene["name"].to_numpy(),
        data=data, keyframe=keyframe,
        ann_sample=_rows(sample["token"], ann["sample_token"]), ann_token=ann["token"].to_numpy(),
        ann_center=to_numpy(ann["translation"], (3,)), ann_size_wlh=to_numpy(ann["size"], (3,)),
        ann_rotation=to_numpy(ann["rotation"], (4,)), ann_velocity=to_numpy(ann["velocity"], (3,)),
        ann_category=ann["category_name"].cast(pl.String).to_numpy(), ann_attribute=ann["attr"].to_numpy(),
        ann_visibility=ann["visibility_token"].to_numpy(),
        ann_num_lidar_pts=ann["num_lidar_pts"].to_numpy(), ann_num_radar_pts=ann["num_radar_pts"].to_numpy())
