"""Which converted output a devkit class serves: `parquet=OUT`, or the `dataroot` given when it is itself one.

The devkit's classes take a `dataroot` (`NuScenes`, `NuScenesCanBus`, ...); ours take the output of `nuparquet
convert` as `parquet=`, or as `dataroot` when no `parquet` is given (then the dataroot the output was converted from,
recorded in its manifest, is where the sensor files are).
"""

from __future__ import annotations

import os
from pathlib import Path

from nuparquet.errors import InputError, UsageError
from nuparquet.format import MANIFEST

DEVKIT_DATAROOT = "/data/sets/nuscenes"  # the devkit's default


def open_output(dataroot: str | os.PathLike | None, parquet: str | os.PathLike | None, *, what: str,
                convert: str, storage_options: dict | None = None):
    """(the `Dataset` to serve, the dataroot the caller gave for the files or None). With `parquet` (a local path, or
    a URL read with `storage_options`) the dataroot given is where the sensor files are: the dataset is opened with
    it, so its sensor reader reads them there.

    `what` names the class in messages; `convert` is the command that makes the output from the dataroot given
    (with `{dataroot}` in it).
    """
    from nuparquet.dataset import open_dataset

    if parquet is None:
        given = dataroot if dataroot is not None else DEVKIT_DATAROOT
        if not (Path(given) / MANIFEST).is_file():
            raise UsageError(
                f"{given} is not a nuparquet output (no {MANIFEST}): pass parquet=OUT, the directory "
                f"`{convert.format(dataroot=given)}` wrote, or give that directory as dataroot")
        dataset, dataroot = open_dataset(given), None
    else:
        dataset = open_dataset(parquet, dataroot=dataroot, storage_options=storage_options)
    return dataset, dataroot


# The devkit class that serves each converted family (`Dataset.source_format`); nuImages has none.
SERVED_BY = {"nuscenes": "nuparquet.devkit.NuScenes", "truckscenes": "nuparquet.devkit.truckscenes.TruckScenes"}
FAMILY = {"nuscenes": "nuScenes", "truckscenes": "MAN TruckScenes", "nuimages": "nuImages"}


def require_format(dataset, expected: str, what: str) -> None:
    """Refuse an output of another dataset family than `expected` (a `Dataset.source_format`), naming its format and
    what serves it: its tables are not the ones `what` (a devkit class) serves."""
    found = dataset.source_format
    if found == expected:
        return
    other = SERVED_BY.get(found)
    instead = f"open it with {other}" if other else "read it with nuparquet.open (no devkit class serves it)"
    raise InputError(f"{dataset.root} is a conversion of {FAMILY.get(found, found)} (source format {found!r}), and "
                     f"{what} serves {FAMILY[expected]} ({expected!r}) outputs only: {instead}")
