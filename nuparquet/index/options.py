"""Options of `nuparquet index` (and `nuparquet.index.build_index`): one dataclass, the CLI flags come from it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nuparquet.errors import UsageError
from nuparquet.options import check_choices, option

# mmdetection3d's converter lists the cameras in this order (dict order of `cams` / `images`): defaults only.
DEFAULT_CAMERAS = ("CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_FRONT_LEFT", "CAM_BACK", "CAM_BACK_LEFT", "CAM_BACK_RIGHT")
DEFAULT_LIDAR = "LIDAR_TOP"


@dataclass
class IndexOptions:
    """Which infos the index writes and how (where: the verb's `out`, `build_index(ds, out, ...)`)."""

    format: Literal["mmdet3d", "bevformer", "mmdet3d-legacy"] = option(
        "mmdet3d", help="mmdet3d: mmdetection3d v1.4's nuScenes infos; bevformer: the BEVFormer/UniAD v1 variant "
        "(needs the sample_can_bus dataset); mmdet3d-legacy: mmdetection3d 0.17's infos (gt_boxes as x, y, z, w, "
        "l, h, -yaw-pi/2) and its nuscenes_infos_<split>_mono3d.coco.json (BEVDet, PETR, FCOS3D...)")
    info_version: Literal[1, 2] = option(2, help="1: create_data.py's first pass (infos + metadata); "
                                         "2: after update_infos_to_v2.py (metainfo + data_list, what mmdet3d 1.x "
                                         "reads). --format mmdet3d only (bevformer needs 1; mmdet3d-legacy has one "
                                         "form and ignores it)")
    max_sweeps: int = option(10, help="lidar sweeps per sample, following the lidar's prev chain")
    split: Literal["train", "val", "test", "all"] = option(
        "all", help="which info files to write; all: every file the converter writes for this version "
        "(train and val, or test for a test version)")
    data_prefix: str = option("./data/nuscenes", help="dataroot as the converter saw it: the prefix of the "
                              "v1 paths and of sweep paths")
    version: str | None = option(None, help="the version the converter was run with (v1.0-trainval, v1.0-test, "
                                 "v1.0-mini); default: the one the dataset's version starts with")
    cameras: tuple[str, ...] = option(DEFAULT_CAMERAS, help="camera channels, in info order (comma-separated)")
    lidar: str = option(DEFAULT_LIDAR, help="the keyframe lidar channel whose prev chain gives the sweeps")
    corrected: bool = option(False, help="also write *_corrected.pkl beside each file: float64 matrices, "
                             "sweep paths like keyframe paths with num_pts_feats, every unmapped class in "
                             "metainfo (see docs)")
    parquet: bool = option(True, help="also write DIR/infos/ (one row per sample, nested columns) with v2 infos")

    def __post_init__(self) -> None:
        check_choices(self)
        cameras = self.cameras.split(",") if isinstance(self.cameras, str) else self.cameras
        self.cameras = tuple(c.strip() for c in cameras if c.strip())  # in info order, once for every layer
        if not self.cameras:
            raise UsageError("--cameras must name at least one camera channel")
        if self.max_sweeps < 0:
            raise UsageError("--max-sweeps must be >= 0")
        if self.format == "bevformer" and self.info_version != 1:
            raise UsageError("--format bevformer writes v1 infos (--info-version 1)")
        if self.corrected and self.format != "mmdet3d":
            raise UsageError("--corrected writes corrected v2 infos: --format mmdet3d only")
