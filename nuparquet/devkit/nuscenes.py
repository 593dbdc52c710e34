"""`NuScenes`: the devkit's database class (`nuscenes.nuscenes.NuScenes`), served from a nuparquet output.

```python
from nuparquet.devkit import NuScenes          # instead of: from nuscenes.nuscenes import NuScenes
nusc = NuScenes("v1.0-trainval", dataroot="/data/nuscenes", parquet="/data/nusc.parquet")
```

Start-up reads `manifest.json` only; each table is read when first used, each record built when first asked for
(`nuparquet.devkit.tables`), the devkit's reverse indexes on first use (`nuparquet.devkit.reverse`). The module is
as long as the devkit's class has methods: each is a thin call into `boxes`, `explorer`, `labels` or the tables.

Longer than our ~300-line norm on purpose: it mirrors a devkit module whose whole surface user code calls, so its
pieces stay where the devkit's users look for them.
"""

from __future__ import annotations

import os
import os.path as osp
import time

import numpy as np

from nuparquet.devkit import boxes as box_calls
from nuparquet.devkit.errors import NotServed
from nuparquet.devkit.explorer import NuScenesExplorer
from nuparquet.devkit.output import open_output, require_format
from nuparquet.devkit.reverse import ReverseIndex
from nuparquet.devkit.tables import ConvertedTables, Table
from nuparquet.devkit.utils.color_map import get_colormap
from nuparquet.devkit.utils.data_classes import Box, LidarPointCloud, PointCloud
from nuparquet.devkit.utils.geometry_utils import BoxVisibility
from nuparquet.devkit.utils.map_mask import MapMask, MissingMapMask
from nuparquet.frames.points import FramesNotConverted
from nuparquet.errors import InputError, UsageError

CORE_TABLES = ("category", "attribute", "visibility", "instance", "sensor", "calibrated_sensor", "ego_pose", "log",
               "scene", "sample", "sample_data", "sample_annotation", "map")
LIDAR_TASKS = ("lidarseg", "panoptic")
# The fields the devkit adds to records (its reverse indexes): not stored columns.
DECORATED = {"sample_annotation": ("category_name",), "sample_data": ("sensor_modality", "channel"),
             "sample": ("data", "anns"), "log": ("map_token",), "map": ("mask",)}


class NuScenes:
    """The devkit's `NuScenes` over a converted nuparquet directory: the same tables, records, reverse indexes and
    answers, read-only.

    Args:
        version: the version folder that was converted (e.g. ``"v1.0-trainval"``); another one is an error.
        dataroot: where the sensor files (and map PNGs) are; the paths this object returns start with it.
            Default: the dataroot the output was converted from (its manifest), or, without `parquet`, the
            converted directory itself given here.
        verbose: print what the devkit prints at start-up (table sizes, from the manifest).
        map_resolution: metres per pixel of the map masks (`map['mask']`), >= 0.1.
        colormap: {class name: (r, g, b)}; default `nuscenes.utils.color_map.get_colormap()`'s.
        parquet: the output directory of `nuparquet convert` (a local path, or a URL polars can scan with
            `storage_options`); may be omitted when `dataroot` is one.
        keep_records: keep every record once built, as the devkit keeps them all (the same dict on every `get`,
            changes stay). False: a new dict on every access and none held, for read-only loops over large tables
            where memory matters more than repeated-lookup speed.
        storage_options: polars' object-store options for a `parquet` URL (as `nuparquet.open` takes them).

    Everything read-only the devkit's object offers is here (see the README's "Switching from the devkit"); the
    pictures (`render_sample_data`, `render_sample`, `render_pointcloud_in_image`, `render_annotation`,
    `render_instance`) are drawn from the Parquet by `nuparquet.rendering.pictures.single` (`devkit.renders`), the scene
    videos raise `NotServed` naming the `nuparquet render` command, and writes raise `ReadOnly`.
    """

    def __init__(self, version: str = "v1.0-mini", dataroot: str | os.PathLike | None = None, verbose: bool = True,
                 map_resolution: float = 0.1, colormap: dict | None = None, *,
                 parquet: str | os.PathLike | None = None, keep_records: bool = True,
                 storage_options: dict | None = None):
        start_time = time.time()
        dataset, dataroot = open_output(dataroot, parquet, what="nuparquet.devkit.NuScenes",
                                        convert=f"nuparquet convert {{dataroot}} --version {version} --out OUT",
                                        storage_options=storage_options)
        require_format(dataset, "nuscenes", "nuparquet.devkit.NuScenes")
        if dataset.version != version:
            raise UsageError(f"version {version!r} was asked for, but {dataset.root} holds the conversion of "
                             f"{dataset.version!r}: pass version={dataset.version!r}, or convert {version!r}")
        assert map_resolution >= 0.1, "Only supports down to 0.1 meter resolution."

        self._arguments = {"version": version, "dataroot": dataroot, "map_resolution": map_resolution,
                           "colormap": colormap, "parquet": dataset.root, "keep_records": keep_records}
        self._keep_records = keep_records
        self.version = version
        self.dataroot = dataroot if dataroot is not None else (dataset.dataroot or str(dataset.root))
        self.verbose = verbose
        self.map_resolution = map_resolution
        self.parquet = dataset.root
        self._dataset = dataset
        self._source = ConvertedTables(dataset)
        converted = set(self._source.names())
        missing = [name for name in CORE_TABLES if name not in converted]
        if missing:
            raise InputError(f"{dataset.root} lacks the table(s) {', '.join(missing)}; convert the dataroot again")
        self.table_names = list(CORE_TABLES)
        decorators = {"sample_annotation": self._decorate_annotation, "sample_data": self._decorate_sample_data,
                      "sample": self._decorate_sample, "log": self._decorate_log, "map": self._decorate_map}
        tables = {}
        if verbose:
            print("======\nLoading NuScenes tables for version {} from {}...".format(self.version, self.parquet))
        for name in CORE_TABLES:
            tables[name] = self._table(name, decorators.get(name))
        self.category = tables["category"]
        self.attribute = tables["attribute"]
        self.visibility = tables["visibility"]
        self.instance = tables["instance"]
        self.sensor = tables["sensor"]
        self.calibrated_sensor = tables["calibrated_sensor"]
        self.ego_pose = tables["ego_pose"]
        self.log = tables["log"]
        self.scene = tables["scene"]
        self.sample = tables["sample"]
        self.sample_data = tables["sample_data"]
        self.sample_annotation = tables["sample_annotation"]
        self.map = tables["map"]

        self.colormap = colormap if colormap is not None else get_colormap()
        lidar_tasks = [t for t in LIDAR_TASKS if t in converted]
        if lidar_tasks:
            self.lidarseg_idx2name_mapping: dict[int, str] = {}
            self.lidarseg_name2idx_mapping: dict[str, int] = {}
            self.load_lidarseg_cat_name_mapping()
        for task in lidar_tasks:
            if verbose:
                print(f"Loading nuScenes-{task}...")
            tables[task] = self._table(task)
            setattr(self, task, tables[task])
            self.table_names.append(task)
            # the colormap in the order of the category indices, as the devkit sorts it
            self.colormap = dict({c["name"]: self.colormap[c["name"]]
                                  for c in sorted(self.category, key=lambda k: k["index"])})
        if "image_annotations" in converted:  # what the devkit's export_2d_annotations_as_json writes
            self.image_annotations = self._table("image_annotations")
        self._tables = tables
        self._index = ReverseIndex(tables, self._source)
        self._by_token = {name: table.by_token for name, table in tables.items()}
        if verbose:
            for name in self.table_names:
                print("{} {},".format(len(tables[name]), name))
            print("Done loading in {:.3f} seconds (records are read on first use).\n======".format(
                time.time() - start_time))
        self.explorer = NuScenesExplorer(self)

    def _table(self, name: str, decorate=None) -> Table:
        return Table(name, self._source.rows(name), lambda: self._source.columns(name), decorate,
                     keep=self._keep_records)

    def __repr__(self) -> str:
        return f"<nuparquet.devkit.NuScenes {self.version} dataroot={self.dataroot!r} parquet={self.parquet!r}>"

    def __reduce__(self):
        """Pickled as its arguments (e.g. for the worker processes of a data loader): the copy opens the same
        output and builds its records again on demand. Changes made to records are not carried over."""
        return _reopen, (self._arguments,)

    @property
    def table_root(self) -> str:
        """The version folder under the dataroot (the devkit reads its JSON tables there)."""
        return osp.join(self.dataroot, self.version)

    # --- the devkit's reverse-index fields, added to each record when it is built ------------------------------

    def _decorate_annotation(self, record: dict, i: int) -> None:
        record["category_name"] = self._index.category_of_instance[record["instance_token"]]

    def _decorate_sample_data(self, record: dict, i: int) -> None:
        record["sensor_modality"], record["channel"] = self._index.sensor_of_calibration[
            record["calibrated_sensor_token"]]

    def _decorate_sample(self, record: dict, i: int) -> None:
        links = self._index.sample_links
        record["data"] = links.data(i)
        record["anns"] = links.anns(i)

    def _decorate_log(self, record: dict, i: int) -> None:
        maps = self._index.map_of_log
        if record["token"] not in maps:
            raise InputError(f"log {record['token']} is in no map's log_tokens: the devkit's NuScenes refuses this "
                             "dataset at start-up (KeyError); add the log to its map record")
        record["map_token"] = maps[record["token"]]

    def _decorate_map(self, record: dict, i: int) -> None:
        path = osp.join(self.dataroot, record["filename"])
        record["mask"] = (MapMask(path, resolution=self.map_resolution) if osp.exists(path)
                          else MissingMapMask(path, resolution=self.map_resolution))

    # --- records ---------------------------------------------------------------------------------------------

    def get(self, table_name: str, token: str) -> dict:
        """The record of `token` in table `table_name` (the same dict object on every call)."""
        try:
            return self._by_token[table_name][token]
        except KeyError:
            pass
        table = self._tables.get(table_name)
        if table is None:
            raise AssertionError(self._no_table(table_name))
        return table.record_of(token)

    def getind(self, table_name: str, token: str) -> int:
        """The index of `token`'s record in `table_name` (file order)."""
        return self._tables[table_name].index_of(token)

    def _no_table(self, table_name: str) -> str:
        message = "Table {} not found".format(table_name)
        if table_name in LIDAR_TASKS:
            message += (f" ({self.parquet} was converted without {table_name}.json: convert a dataroot whose "
                        f"{self.version}/ holds it)")
        return message

    def field2token(self, table_name: str, field: str, query) -> list[str]:
        """Tokens of the records of `table_name` whose `field` equals `query` (Python's ==), in file order."""
        table = self._tables.get(table_name) or getattr(self, table_name)
        if not len(table):
            return []
        if field not in DECORATED.get(table_name, ()):
            matches = table.columns.tokens_where(field, query)  # the stored column, when it answers exactly
            if matches is not None:
                return matches
        return [member["token"] for member in table if member[field] == query]

    def get_sample_data_path(self, sample_data_token: str) -> str:
        """The sensor file of a sample_data record: dataroot joined with its filename."""
        sd_record = self.get("sample_data", sample_data_token)
        return osp.join(self.dataroot, sd_record["filename"])

    # --- boxes -----------------------------------------------------------------------------------------------

    def get_sample_data(self, sample_data_token: str, box_vis_level: BoxVisibility = BoxVisibility.ANY,
                        selected_anntokens: list[str] | None = None, use_flat_vehicle_coordinates: bool = False):
        """(data path, boxes in the sensor frame, camera intrinsic (3, 3) or None), as the devkit's: for a camera,
        only the boxes passing `box_in_image(box_vis_level)`; `selected_anntokens` instead of the frame's boxes;
        `use_flat_vehicle_coordinates`: the ego frame turned by the pose's yaw only, instead of the sensor frame."""
        return box_calls.get_sample_data(self, sample_data_token, box_vis_level, selected_anntokens,
                                         use_flat_vehicle_coordinates)

    def get_box(self, sample_annotation_token: str) -> Box:
        """The annotation as a `Box` in the global frame."""
        record = self.get("sample_annotation", sample_annotation_token)
        return Box(record["translation"], record["size"], _quaternion(record["rotation"]),
                   name=record["category_name"], token=record["token"])

    def get_boxes(self, sample_data_token: str) -> list[Box]:
        """The frame's boxes in the global frame: its sample's annotations, interpolated to a sweep's time."""
        return box_calls.get_boxes(self, sample_data_token)

    def box_velocity(self, sample_annotation_token: str, max_time_diff: float = 1.5) -> np.ndarray:
        """(3,) velocity in m/s from the annotation's track neighbours (NaN when it cannot be estimated)."""
        return box_calls.box_velocity(self, sample_annotation_token, max_time_diff)

    # --- points and labels -------------------------------------------------------------------------------------

    def _point_cloud(self, sd_record: dict, cls: type[PointCloud]) -> PointCloud:
        """The cloud of one sample_data record for `PointCloud.from_file_multisweep`: its file under the dataroot,
        else the converted points (`lidar_points/`, `radar_points/`)."""
        path = osp.join(self.dataroot, sd_record["filename"])
        if osp.exists(path):
            return cls.from_file(path)
        dataset = "lidar_points" if issubclass(cls, LidarPointCloud) else "radar_points"
        if dataset in self._dataset.datasets:
            try:
                if dataset == "lidar_points":
                    return cls(np.ascontiguousarray(self._dataset.points(sd_record["token"])[:, :4].T))
                return cls._filtered(self._dataset.radar_points(sd_record["token"]).T.copy())
            except FramesNotConverted:
                pass  # not converted (a sweep without --sweeps): say so below
        sweeps = "" if sd_record["is_key_frame"] else " --sweeps"
        raise FileNotFoundError(f"{path} does not exist, and {self.parquet} holds no points of sample_data "
                                f"{sd_record['token']}: give the dataroot with the sensor files, or convert with "
                                f"--sensors {dataset.split('_')[0]}{sweeps}")

    def load_lidarseg_cat_name_mapping(self) -> None:
        """Fill `lidarseg_idx2name_mapping` and `lidarseg_name2idx_mapping` from the category table's `index`."""
        for category in self.category:
            assert "index" in category.keys(), \
                "Please use the category.json that comes with nuScenes-lidarseg, and not the old category.json."
            self.lidarseg_idx2name_mapping[category["index"]] = category["name"]
            self.lidarseg_name2idx_mapping[category["name"]] = category["index"]

    def get_sample_lidarseg_stats(self, sample_token: str, sort_by: str = "count", lidarseg_preds_bin_path: str = None,
                                  gt_from: str = "lidarseg") -> None:
        """Print the number of points of each class in the sample's LIDAR_TOP cloud (classes without points are
        left out), sorted by count, name or index; from the converted labels, or the label files."""
        self.explorer.sample_lidarseg_stats(sample_token, sort_by, lidarseg_preds_bin_path, gt_from)

    # --- printers (NuScenesExplorer) ---------------------------------------------------------------------------

    def list_categories(self) -> None:
        self.explorer.list_categories()

    def list_lidarseg_categories(self, sort_by: str = "count", gt_from: str = "lidarseg") -> None:
        self.explorer.list_lidarseg_categories(sort_by=sort_by, gt_from=gt_from)

    def list_panoptic_instances(self, sort_by: str = "count", get_hist: bool = False) -> None:
        self.explorer.list_panoptic_instances(sort_by=sort_by, get_hist=get_hist)

    def list_attributes(self) -> None:
        self.explorer.list_attributes()

    def list_scenes(self) -> None:
        self.explorer.list_scenes()

    def list_sample(self, sample_token: str) -> None:
        self.explorer.list_sample(sample_token)

    # --- renderers: `devkit.renders` (pictures from `nuparquet.rendering.pictures.single`; the videos refused) -------------

    def render_pointcloud_in_image(self, sample_token: str, dot_size: int = 5, pointsensor_channel: str = "LIDAR_TOP",
                                   camera_channel: str = "CAM_FRONT", out_path: str | None = None,
                                   render_intensity: bool = False, show_lidarseg: bool = False,
                                   filter_lidarseg_labels=None, show_lidarseg_legend: bool = False,
                                   verbose: bool = True, lidarseg_preds_bin_path: str | None = None,
                                   show_panoptic: bool = False):
        # the devkit's NuScenes takes no `ax` here, so its positional order differs from the explorer's
        return self.explorer.render_pointcloud_in_image(
            sample_token, dot_size, pointsensor_channel=pointsensor_channel, camera_channel=camera_channel,
            out_path=out_path, render_intensity=render_intensity, show_lidarseg=show_lidarseg,
            filter_lidarseg_labels=filter_lidarseg_labels, show_lidarseg_legend=show_lidarseg_legend,
            verbose=verbose, lidarseg_preds_bin_path=lidarseg_preds_bin_path, show_panoptic=show_panoptic)

    def render_sample(self, *args, **kwargs):
        return self.explorer.render_sample(*args, **kwargs)

    def render_sample_data(self, *args, **kwargs):
        return self.explorer.render_sample_data(*args, **kwargs)

    def render_annotation(self, *args, **kwargs):
        return self.explorer.render_annotation(*args, **kwargs)

    def render_instance(self, *args, **kwargs):
        return self.explorer.render_instance(*args, **kwargs)

    def render_scene(self, *args, **kwargs) -> None:
        self.explorer.render_scene(*args, **kwargs)

    def render_scene_channel(self, *args, **kwargs) -> None:
        self.explorer.render_scene_channel(*args, **kwargs)

    def render_egoposes_on_map(self, *args, **kwargs) -> None:
        self.explorer.render_egoposes_on_map(*args, **kwargs)

    def render_scene_channel_lidarseg(self, *args, **kwargs) -> None:
        self.explorer.render_scene_channel_lidarseg(*args, **kwargs)

    def render_scene_lidarseg(self, *args, **kwargs) -> None:
        self.explorer.render_scene_lidarseg(*args, **kwargs)


def _reopen(arguments: dict) -> NuScenes:
    return NuScenes(**arguments, verbose=False)


def _quaternion(rotation):
    from pyquaternion import Quaternion

    return Quaternion(rotation)


__all__ = ["NuScenes", "NuScenesExplorer", "NotServed"]
