"""truckscenes-devkit's `TruckScenes` (`truckscenes.TruckScenes`), served from a converted MAN TruckScenes output.

```python
from nuparquet.devkit.truckscenes import TruckScenes      # instead of: from truckscenes import TruckScenes
ts = TruckScenes("v1.2-mini", dataroot="/data/man-truckscenes", parquet="/data/ts.parquet")
```

The same machinery as `nuparquet.devkit.NuScenes`, of which it is a subclass: the converted tables as lazy lists of
dicts (`devkit.tables`), the reverse indexes built on first use (`devkit.reverse`), the box calls of `devkit.boxes`.
What truckscenes-devkit does differently is kept: its tables (no log or map; `ego_motion_cabin`,
`ego_motion_chassis`, and `weather_annotation`, empty when not converted), `getclosest`, `get_sample_data` moving the
boxes with the ego pose nearest the *sample's* time (not the frame's own pose) and, in the flat vehicle frame,
turning each box a quarter turn about its own up axis, `boxes_to_sensor`, its explorer's printers and scene filters
(`devkit.truckscenes_explorer`). `get_box`, `get_boxes` and `box_velocity` are nuScenes' arithmetic, as in the
devkit. Not served: the renderers (`NotServed`, naming `nuparquet render`) and the points of
`from_file_multisweep` (`nuparquet.frames.sweeps.multisweep` does it); the nuScenes-only calls (lidarseg, the map)
are absent, as on the devkit's object.
"""

from __future__ import annotations

import os
import time
import warnings

import numpy as np
from pyquaternion import Quaternion

from nuparquet.devkit import boxes as box_calls
from nuparquet.devkit.errors import NotServed
from nuparquet.devkit.nuscenes import NuScenes
from nuparquet.devkit.output import open_output, require_format
from nuparquet.devkit.reverse import ReverseIndex
from nuparquet.devkit.tables import ConvertedTables, Table
from nuparquet.devkit.truckscenes_explorer import RENDERERS, TruckScenesExplorer, get_colormap
from nuparquet.devkit.utils.data_classes import Box
from nuparquet.devkit.utils.geometry_utils import BoxVisibility
from nuparquet.errors import InputError, UsageError
from nuparquet.geometry.interpolation import ClosestRows

# truckscenes-devkit's `table_names`, in its order.
TABLES = ("attribute", "calibrated_sensor", "category", "ego_motion_cabin", "ego_motion_chassis", "ego_pose",
          "instance", "sample", "sample_annotation", "sample_data", "scene", "sensor", "visibility",
          "weather_annotation")
OPTIONAL = ("weather_annotation",)  # before v1.1: the devkit warns and loads []
TIMED = ("ego_pose", "ego_motion_cabin", "ego_motion_chassis", "sample", "sample_data")  # getclosest's tables
DATAROOT = "/data/man-truckscenes"  # the devkit's default
WHAT = "nuparquet.devkit.truckscenes.TruckScenes"


class _NuScenesOnly:
    """A `NuScenes` call truckscenes-devkit's object does not have: AttributeError, as there (`hasattr` is False)."""

    def __init__(self, name: str):
        self.name = name

    def __get__(self, obj, objtype=None):
        raise AttributeError(f"'TruckScenes' object has no attribute {self.name!r} (a nuscenes-devkit call: "
                             "truckscenes-devkit's TruckScenes has none)")


class TruckScenes(NuScenes):
    """truckscenes-devkit's `TruckScenes` over a converted TruckScenes directory: the same tables, records, reverse
    indexes and answers, read-only.

    Args:
        version: the version folder that was converted (e.g. ``"v1.2-mini"``); None: the converted one (the devkit
            picks the latest in its dataroot); another one is an error.
        dataroot: where the sensor files are; the paths this object returns start with it. Default: the dataroot
            the output was converted from (its manifest), or, without `parquet`, the converted directory itself
            given here (the devkit's default ``/data/man-truckscenes`` when neither is given).
        verbose: print what the devkit prints at start-up (table sizes, from the manifest).
        parquet, keep_records, storage_options: as `nuparquet.devkit.NuScenes`'.
    """

    def __init__(self, version: str | None = None, dataroot: str | os.PathLike | None = None, verbose: bool = True,
                 *, parquet: str | os.PathLike | None = None, keep_records: bool = True,
                 storage_options: dict | None = None):
        start_time = time.time()
        given = dataroot if dataroot is not None or parquet is not None else DATAROOT
        dataset, dataroot = open_output(given, parquet, what=WHAT, storage_options=storage_options,
                                        convert=f"nuparquet convert {{dataroot}} --version {version or 'VERSION'} "
                                                "--out OUT")
        require_format(dataset, "truckscenes", WHAT)
        if version is None:
            version = dataset.version
        elif dataset.version != version:
            raise UsageError(f"version {version!r} was asked for, but {dataset.root} holds the conversion of "
                             f"{dataset.version!r}: pass version={dataset.version!r}, or convert {version!r}")
        self._arguments = {"version": version, "dataroot": dataroot, "parquet": dataset.root,
                           "keep_records": keep_records}
        self._keep_records = keep_records
        self.version = version
        self.dataroot = dataroot if dataroot is not None else (dataset.dataroot or str(dataset.root))
        self.verbose = verbose
        self.parquet = dataset.root
        self._dataset = dataset
        self._source = ConvertedTables(dataset)
        converted = set(self._source.names())
        missing = [name for name in TABLES if name not in converted and name not in OPTIONAL]
        if missing:
            raise InputError(f"{dataset.root} lacks the table(s) {', '.join(missing)}; convert the dataroot again")
        self.table_names = list(TABLES)
        if verbose:
            print(f"======\nLoading truckscenes tables for version {self.version} from {self.parquet}...")
        decorators = {"sample_annotation": self._decorate_annotation, "sample_data": self._decorate_sample_data,
                      "sample": self._decorate_sample}
        self._absent = frozenset(name for name in OPTIONAL if name not in converted)
        tables = {}
        for name in TABLES:
            if name in self._absent:
                warnings.warn(f"{name}s.json was not found. It's available starting from v1.1")
                tables[name] = Table(name, 0, _never_read)
            else:
                tables[name] = self._table(name, decorators.get(name))
            setattr(self, name, tables[name])
        self.colormap = get_colormap()
        self._tables = tables
        self._index = ReverseIndex(tables, self._source)
        self._by_token = {name: table.by_token for name, table in tables.items()}
        self._closest: dict[str, ClosestRows] = {}
        if verbose:
            for name in self.table_names:
                print(f"{len(tables[name])} {name},")
            print(f"Done loading in {time.time() - start_time:.3f} seconds (records and reverse indexes are built "
                  "on first use).\n======")
        self.explorer = TruckScenesExplorer(self)

    def __repr__(self) -> str:
        return f"<{WHAT} {self.version} dataroot={self.dataroot!r} parquet={self.parquet!r}>"

    def __reduce__(self):
        """Pickled as its arguments, as `NuScenes`: the copy opens the same output again."""
        return _reopen, (self._arguments,)

    # --- records ---------------------------------------------------------------------------------------------

    def get(self, table_name: str, token: str) -> dict:
        """The record of `token` in table `table_name` (the same dict object on every call); a table that was not
        converted (`weather_annotation` before v1.1) has none: KeyError, as the devkit's empty table."""
        if table_name in self._absent:
            raise KeyError(token)
        return super().get(table_name, token)

    def getind(self, table_name: str, token: str) -> int:
        if table_name in self._absent:
            raise KeyError(token)
        return super().getind(table_name, token)

    def getclosest(self, table_name: str, timestamp: int) -> dict:
        """The record of `table_name` (ego_pose, ego_motion_cabin, ego_motion_chassis, sample, sample_data) nearest
        `timestamp`, as the devkit's: a tie goes to the earlier time, and of records sharing a timestamp the last in
        file order (`geometry.interpolation.ClosestRows`)."""
        assert table_name in TIMED, f"Table {table_name} has no timestamp"
        closest = self._closest.get(table_name)
        if closest is None:
            stamps = self._source.read(table_name, ["timestamp"]).column("timestamp").to_numpy()
            closest = self._closest[table_name] = ClosestRows(np.asarray(stamps, dtype=np.int64))
        return self._tables[table_name].record(int(closest(np.asarray([timestamp]))[0]))

    # --- boxes -----------------------------------------------------------------------------------------------

    def get_sample_data(self, sample_data_token: str, box_vis_level: BoxVisibility = BoxVisibility.ANY,
                        selected_anntokens: list[str] | None = None, use_flat_vehicle_coordinates: bool = False):
        """(data path, boxes in the sensor frame, camera intrinsic (3, 3) or None), as truckscenes-devkit's: the
        boxes moved with the ego pose nearest the sample's time; for a camera, only those passing
        `box_in_image(box_vis_level)`; `use_flat_vehicle_coordinates`: the ego frame turned by the pose's yaw, each
        box then turned a quarter about its own up axis (the devkit's "rotate upwards")."""
        sd_record = self.get("sample_data", sample_data_token)
        pose_record = self.getclosest("ego_pose", self.get("sample", sd_record["sample_token"])["timestamp"])
        return box_calls.get_sample_data(self, sample_data_token, box_vis_level, selected_anntokens,
                                         use_flat_vehicle_coordinates, pose_record=pose_record,
                                         turn=_upright if use_flat_vehicle_coordinates else None)

    def boxes_to_sensor(self, boxes: list[Box], pose_record: dict, cs_record: dict,
                        use_flat_vehicle_coordinates: bool = False) -> list[Box]:
        """The devkit's `boxes_to_sensor`: each box moved in place from the global frame to the sensor's (or the
        flat ego frame), with its own `Box.translate` / `Box.rotate` steps (velocities turned too)."""
        out = []
        for box in boxes:
            box.translate(-np.array(pose_record["translation"]))
            if use_flat_vehicle_coordinates:
                yaw = Quaternion(pose_record["rotation"]).yaw_pitch_roll[0]
                box.rotate(Quaternion(scalar=np.cos(yaw / 2), vector=[0, 0, np.sin(yaw / 2)]).inverse)
                _upright(box)
            else:
                box.rotate(Quaternion(pose_record["rotation"]).inverse)
                box.translate(-np.array(cs_record["translation"]))
                box.rotate(Quaternion(cs_record["rotation"]).inverse)
            out.append(box)
        return out

    def _point_cloud(self, sd_record: dict, cls):
        raise NotServed("from_file_multisweep is not served on a TruckScenes output (its clouds are .pcd files): "
                        "nuparquet.frames.sweeps.multisweep(nuparquet.open(OUT, dataroot=...), sample_token, channel, "
                        "ref_channel, nsweeps) gives truckscenes-devkit's from_file_multisweep points and times")

    # --- the explorer's printers and filters (`devkit.truckscenes_explorer`) ----------------------------------

    def get_scenes_weather_annotations_filtered(self, conditions: list[tuple[str, str, float]]) -> list[str]:
        return self.explorer.get_scenes_weather_annotations_filtered(conditions)

    def get_scenes_description_filtered(self, conditions: list[tuple[str, str]]) -> list[str]:
        return self.explorer.get_scenes_description_filtered(conditions)


NUSCENES_ONLY = ("load_lidarseg_cat_name_mapping", "get_sample_lidarseg_stats", "list_lidarseg_categories",
                 "list_panoptic_instances", "render_egoposes_on_map", "render_scene_channel_lidarseg",
                 "render_scene_lidarseg")
for _name in NUSCENES_ONLY:
    setattr(TruckScenes, _name, _NuScenesOnly(_name))
for _name in RENDERERS:  # the devkit's renderers: refused by the explorer, with what draws instead
    setattr(TruckScenes, _name, getattr(TruckScenesExplorer, _name))


def _upright(box: Box) -> None:
    """truckscenes-devkit's flat-frame step after the yaw: a quarter turn about the box's own up axis."""
    box.rotate(Quaternion(axis=box.orientation.rotate([0, 0, 1]), angle=np.pi / 2))


def _never_read():
    raise KeyError("a table that was not converted has no columns")


def _reopen(arguments: dict) -> TruckScenes:
    return TruckScenes(**arguments, verbose=False)


__all__ = ["TruckScenes", "TruckScenesExplorer", "NotServed"]
