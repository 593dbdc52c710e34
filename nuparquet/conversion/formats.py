"""The source formats `nuparquet convert` reads, registered in one place and told apart by their version folder.

A `SourceFormat` is what differs between dataset families of the nuScenes layout: how the tables are read, how
they are checked, which datasets are built beside `tables/`, and which channel facts the manifest records.
`detect_format` walks `FORMATS` in order and takes the first whose `detect` accepts the version folder; nuScenes
(and the datasets that copy it exactly: Lyft Level 5, TIER IV T4) is last and accepts any folder.
`convert --source-format NAME` names one instead of detecting it.

A new family is one entry here (its reader in `sources/`, its builders in `builders/`), placed before nuScenes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import polars as pl

from nuparquet.channels import channel_facts
from nuparquet.conversion.builder import Builder
from nuparquet.conversion.builders import ego_motion
from nuparquet.conversion.builders import nuimages as nuimages_builders
from nuparquet.conversion.registry import BUILDERS
from nuparquet.errors import UsageError
from nuparquet.problems import Problem
from nuparquet.schemas import table_schemas
from nuparquet.sources import nuimages, truckscenes
from nuparquet.sources.integrity import check_integrity
from nuparquet.sources.tables import ReadResult, read_tables, version_dir

AUTO = "auto"


@dataclass(frozen=True)
class SourceFormat:
    name: str
    doc: str
    detect: Callable[[Path], bool]  # the version folder holds this format
    read: Callable[..., ReadResult]  # (dataroot, version, *, on_table=, finish=) as `sources.tables.read_tables`
    check: Callable[..., list[Problem]]  # (tables, *, references=) as `sources.integrity.check_integrity`
    builders: tuple[Builder, ...]
    channels: Callable[[dict[str, pl.DataFrame]], dict]  # the manifest's "channels"
    steps: int  # progress units of reading (one per table it knows)
    # Columns of the derived datasets this format cannot fill (TruckScenes has no log): written as nullable.
    nullable_fields: tuple[str, ...] = ()


def nuscenes_channels(tables: dict[str, pl.DataFrame]) -> dict:
    """The dataset's channels (`nuparquet.channels.channel_facts`): names, modalities, one calibration's yaw each."""
    sensors = tables["sensor"]
    calibrations = (tables["calibrated_sensor"].join(sensors.select(pl.col("token").alias("sensor_token"), "channel"),
                                                on="sensor_token")
                    .sort("channel", "token").unique("channel", keep="first", maintain_order=True))
    rotations = dict(zip(calibrations["channel"].to_list(), calibrations["rotation"].to_list()))
    return channel_facts(sensors["channel"].to_list(), sensors["modality"].to_list(), rotations)


def _camera_channels(tables: dict[str, pl.DataFrame]) -> dict:
    """nuImages: cameras only, no lidar to refer to."""
    names = sorted(set(tables["sensor"]["channel"].to_list()))
    return {"reference_lidar": None, "cameras": names, "camera_layout": [names], "lidars": [], "radars": []}


NUSCENES = SourceFormat(
    "nuscenes", "nuScenes and the datasets of its exact layout (Lyft Level 5, TIER IV T4)", lambda folder: True,
    read_tables, check_integrity, BUILDERS, nuscenes_channels, len(table_schemas()))
NUIMAGES = SourceFormat(
    "nuimages", "nuImages: keyframe images with 2D boxes, instance and surface masks (nuscenes-devkit's nuimages)",
    nuimages.looks_like, nuimages.read_nuimages_tables, nuimages.check_nuimages, nuimages_builders.BUILDERS,
    _camera_channels, len(nuimages.schemas()))

TRUCKSCENES = SourceFormat(
    "truckscenes", "MAN TruckScenes: nuScenes' layout without log and map, with ego motion of cabin and chassis, "
    "weather, 4 cameras, 6 lidars and 6 radars as .pcd (truckscenes-devkit)", truckscenes.looks_like,
    truckscenes.read_truckscenes_tables, truckscenes.check_truckscenes, (*BUILDERS, ego_motion.BUILDER), nuscenes_channels,
    len(truckscenes.schemas()) + 1, nullable_fields=truckscenes.LOG_COLUMNS)

FORMATS: tuple[SourceFormat, ...] = (NUIMAGES, TRUCKSCENES, NUSCENES)  # detection order: nuScenes, which takes anything, last
FORMAT_NAMES = (AUTO, *(f.name for f in FORMATS))


def detect_format(dataroot: Path | str, version: str, name: str = AUTO) -> SourceFormat:
    """The format of `dataroot/version`: the one named, or the first of `FORMATS` whose `detect` accepts it."""
    if name != AUTO:
        for fmt in FORMATS:
            if fmt.name == name:
                return fmt
        raise UsageError(f"--source-format must be one of {', '.join(FORMAT_NAMES)}, got {name!r}")
    folder = version_dir(dataroot, version)
    return next(fmt for fmt in FORMATS if fmt.detect(folder))
