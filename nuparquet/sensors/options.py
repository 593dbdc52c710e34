"""Where the sensor files a dataset does not hold are (camera images, point clouds not converted): the one
`--dataroot` flag of every command that reads them (`render`, `export-mcap`, `report`). Light: no polars."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from nuparquet.options import option


@dataclass
class SensorFiles:
    """The dataroot to read sensor files from (`nuparquet.open(OUT, dataroot=...)` in Python)."""

    dataroot: str | Path | None = option(
        None, metavar="PATH", help="where the sensor files are (samples/, sweeps/: images and point clouds not "
        "converted), if not at the dataroot recorded at conversion")
