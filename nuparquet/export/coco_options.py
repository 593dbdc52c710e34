"""What `nuparquet export-coco` (and `nuparquet.export_coco`) can be asked to write: light on purpose (the CLI
builds its flags from it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nuparquet.errors import UsageError
from nuparquet.options import option

CLASS_SETS = ("mmdet3d", "all")


@dataclass
class CocoOptions:
    classes: Literal["mmdet3d", "all"] = option(
        "mmdet3d", help="mmdet3d (default): the file mmdetection3d's tools/dataset_converters/nuimage_converter.py "
        "writes, byte for byte (its 10 nuScenes classes with ids from 0, the box's area, objects of other classes "
        "left out); all: every object category of category.json with the devkit's class index as id, a "
        "supercategory, and the mask's area")
    overwrite: bool = option(False, help="replace the output file if it exists")

    def __post_init__(self) -> None:
        if self.classes not in CLASS_SETS:
            raise UsageError(f"--classes must be one of {', '.join(CLASS_SETS)}, got {self.classes!r}")
