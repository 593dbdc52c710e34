"""`Dataset`: one converted directory, its manifest, a lazy polars scan per dataset, and the questions people ask
of it first (boxes of frames, projected boxes, points, the map, SQL).

Longer than our ~300-line norm on purpose: it is the face users read, so every method keeps its docstring here,
while the work is done elsewhere (`frames/`, `map/`, `dataset.sql`, `dataset.manifest`)."""

from __future__ import annotations

import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import polars as pl

from nuparquet.dataset.manifest import load_manifest
from nuparquet.dataset.sql import run_sql, sql_names
from nuparquet.dataset.storage import is_url
from nuparquet.errors import FormatError, UsageError
from nuparquet.format import MANIFEST

if TYPE_CHECKING:
    import numpy as np

    from nuparquet.frames.projection import ProjectedBoxes
    from nuparquet.map.queries import MapLayers

# A frames selection: one sample_data token, a list of them, or rows of `frames` (DataFrame or LazyFrame).
Frames = "str | Sequence[str] | pl.DataFrame | pl.LazyFrame"


class Dataset:
    """A converted nuparquet directory: its manifest and one lazy polars scan per dataset.

    Attributes: `root` (the path or URL as given, without a trailing slash), `manifest` (the parsed
    manifest.json), `datasets` (names, in manifest order), `dataroot` (where the sensor files are: the one given
    when opening, else the nuScenes dataroot it was converted from, as recorded in the manifest), `version` (the
    source version, e.g. ``v1.0-mini``), `storage_options` (polars' object-store options, used for the manifest and
    every scan).
    """

    def __init__(self, root: str, manifest: dict, storage_options: Mapping[str, Any] | None = None,
                 dataroot: str | Path | None = None):
        self.root = root
        self.manifest = manifest
        self.storage_options = dict(storage_options) if storage_options else None
        self._dataroot = str(dataroot) if dataroot is not None else None
        self._sensors = None
        self._filesystem = None
        self._entries: dict[str, dict] = dict(manifest["datasets"])
        self._channels: dict | None = None
        self._scene_names: list[str] | None = None
        self._maps: dict[str, MapLayers] = {}
        self._row_groups: dict[str, Any] = {}  # points dataset -> frames.points.RowGroupIndex (footers, read once)

    def __repr__(self) -> str:
        return f"<nuparquet.Dataset {self.root!r} {self.version} datasets={len(self.datasets)}>"

    # -- what it holds ----------------------------------------------------------------------------------------

    @property
    def is_remote(self) -> bool:
        return is_url(self.root)

    @property
    def datasets(self) -> list[str]:
        return list(self._entries)

    @property
    def dataroot(self) -> str | None:
        """Where the sensor files are: the dataroot given when opening, else the one recorded at conversion."""
        return self._dataroot if self._dataroot is not None else self.manifest.get("source", {}).get("dataroot")

    @property
    def sensors(self):
        """The one reader of this dataset's sensor data (`nuparquet.sensors.reader.SensorReader`)."""
        if self._sensors is None:
            from nuparquet.sensors.reader import SensorReader

            self._sensors = SensorReader(self)
        return self._sensors

    @property
    def reference(self) -> DatasetReference:
        """A small picklable handle that opens this dataset again (in an engine worker): root, storage options,
        dataroot."""
        root = str(self.root) if self.is_remote else str(Path(self.root).resolve())
        return DatasetReference(root, self.storage_options, self._dataroot)

    @property
    def version(self) -> str | None:
        return self.manifest.get("source", {}).get("version")

    @property
    def channels(self) -> dict:
        """The dataset's sensor channels (`nuparquet.channels.channel_facts`): {"reference_lidar": str | None,
        "cameras": [...], "camera_layout": [[front row], [back row]], "lidars": [...], "radars": [...]}.

        Recorded in manifest.json at conversion; for an output written before that, computed once from
        `tables/sensor` and the camera calibrations in `tables/calibrated_sensor` (else from `frames`).
        """
        recorded = self.manifest.get("channels")
        if isinstance(recorded, dict):
            return recorded
        if self._channels is None:
            from nuparquet.channels import channels_of_dataset

            self._channels = channels_of_dataset(self)
        return self._channels

    def scene_names(self) -> list[str]:
        """Every scene's name, sorted (read once)."""
        if self._scene_names is None:
            self._scene_names = sorted(self.scan("scenes").select("name").collect()["name"].to_list())
        return self._scene_names

    def check_scenes(self, names: Sequence[str]) -> None:
        """UsageError naming each scene of `names` the dataset does not hold, with the closest names and the valid
        ones (the one check behind every command and method that takes a scene)."""
        known = self.scene_names()
        known_set = set(known)
        unknown = [name for name in names if name not in known_set]
        if not unknown:
            return
        close = [match for name in unknown for match in difflib.get_close_matches(name, known, n=2, cutoff=0.8)]
        hint = f" (did you mean {', '.join(dict.fromkeys(close))}?)" if close else ""
        shown = ", ".join(known[:20]) + (f" ... ({len(known)} in all)" if len(known) > 20 else "")
        raise UsageError(f"unknown scene{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}{hint}; "
                         f"valid scenes: {shown or '(none)'}")

    def check_channel(self, channel: str, modalities: Sequence[str] = ("camera", "lidar", "radar")) -> None:
        """UsageError unless `channel` is one of the dataset's channels of `modalities` (the valid ones listed)."""
        facts = self.channels
        valid = sorted({c for modality in modalities for c in facts.get(f"{modality}s", [])}
                       | ({facts["reference_lidar"]} if "lidar" in modalities and facts.get("reference_lidar") else set()))
        if channel not in valid:
            raise UsageError(f"unknown {'/'.join(modalities)} channel {channel!r}; valid: {', '.join(valid) or '(none)'}")

    # -- reading ----------------------------------------------------------------------------------------------

    def _entry(self, name: str) -> dict:
        if name not in self._entries:
            names = sorted(self.datasets, key=lambda n: n.startswith("tables/"))  # derived datasets first
            raise UsageError(f"no dataset {name!r} in {self.root}; valid names: {', '.join(names)}")
        return self._entries[name]

    def location(self, name: str) -> str:
        """The directory (path or URL) of dataset `name`."""
        return f"{self.root}/{self._entry(name).get('path', name)}"

    def scan(self, name: str, **scan_options: Any) -> pl.LazyFrame:
        """A lazy scan of dataset `name`: any name `sql` takes (``"annotations"``, ``"frames"``, ``"tables/sample"``,
        ``"sample"``, ``"tables_sample"``, ``"map/lane"``, ...).

        Nothing is read here: polars reads only the columns and row groups the collected query needs
        (row-group statistics prune filters on sorted columns such as ``scene_name``). `scan_options` go to
        `polars.scan_parquet`; the dataset's `storage_options` are passed on.
        """
        name = self.sql_names().get(name, name)
        location = self.location(name)
        if not self.is_remote and not Path(location).is_dir():
            raise FormatError(f"{self.root}: dataset {name!r} is listed in {MANIFEST} but {location} is missing")
        options: dict[str, Any] = {"hive_partitioning": True}
        if self.storage_options:
            options["storage_options"] = self.storage_options
        options.update(scan_options)
        return pl.scan_parquet(f"{location}/**/*.parquet", **options)

    def files(self, name: str) -> list[tuple[str, int]]:
        """The Parquet files of dataset `name` with their sizes in bytes: local paths, or for an object store the
        paths inside `self.filesystem` (listed through it, with the dataset's storage options)."""
        if self.is_remote:
            import pyarrow.fs as pafs

            filesystem, base = self.filesystem
            selector = pafs.FileSelector(f"{base}/{self._entry(name).get('path', name)}", recursive=True)
            infos = [i for i in filesystem.get_file_info(selector) if i.type == pafs.FileType.File
                     and i.path.endswith(".parquet")]
            return [(i.path, i.size) for i in sorted(infos, key=lambda i: i.path)]
        location = Path(self.location(name))
        return [(str(p), p.stat().st_size) for p in sorted(location.rglob("*.parquet"))]

    @property
    def filesystem(self):
        """(pyarrow FileSystem, the root's path in it) for an object-store dataset, from its storage options (what
        pyarrow reads itself: the row groups of chosen frames); None for a local folder."""
        if not self.is_remote:
            return None
        if self._filesystem is None:
            from nuparquet.dataset.storage import arrow_filesystem

            self._filesystem = arrow_filesystem(self.root, self.storage_options)
        return self._filesystem

    def damaged_files(self) -> list[tuple[str, str]]:
        """Parquet files of this output whose footer cannot be read (truncated, overwritten), with the reason.
        Reads footers only (local directories only)."""
        import pyarrow.parquet as pq

        damaged = []
        for name in self.datasets:
            for path, _ in self.files(name):
                try:
                    pq.read_metadata(path)
                except Exception as exc:  # noqa: BLE001 - any unreadable footer is what we look for
                    damaged.append((path, str(exc).splitlines()[0] if str(exc) else type(exc).__name__))
        return damaged

    def row_count(self, name: str) -> int:
        """Rows of dataset `name`, from the Parquet footers (no data pages read)."""
        return int(self.scan(name).select(pl.len()).collect().item())

    def inventory(self) -> pl.DataFrame:
        """One row per dataset: ``dataset``, ``rows`` (counted from the Parquet footers), ``manifest_rows``,
        ``files`` and ``bytes`` on disk (for a URL: from the manifest, ``files`` null)."""
        rows = []
        for name in self.datasets:
            entry = self._entries[name]
            if self.is_remote:
                files, size = None, entry.get("bytes")
            else:
                listing = self.files(name)
                files, size = len(listing), sum(s for _, s in listing)
            rows.append({"dataset": name, "rows": self.row_count(name), "manifest_rows": entry.get("rows"),
                         "files": files, "bytes": size})
        return pl.DataFrame(rows, schema={"dataset": pl.String, "rows": pl.Int64, "manifest_rows": pl.Int64,
                                          "files": pl.Int64, "bytes": pl.Int64})

    # -- SQL --------------------------------------------------------------------------------------------------

    def sql_names(self) -> dict[str, str]:
        """Every SQL name `sql` registers (and `scan` takes), mapped to the dataset it stands for
        (`nuparquet.dataset.sql`)."""
        return sql_names(self.datasets)

    def sql_context(self) -> pl.SQLContext:
        """A polars SQLContext with every dataset registered lazily under the names of `sql_names`."""
        context = pl.SQLContext()
        scans = {name: self.scan(name) for name in self.datasets}
        for sql_name, name in self.sql_names().items():
            context.register(sql_name, scans[name])
        return context

    def sql(self, query: str, *, lazy: bool = False, allow_file_access: bool = False) -> pl.DataFrame | pl.LazyFrame:
        """Run polars SQL over every dataset (names: `nuparquet.dataset.sql`; ``"map/lane"`` double-quoted) and
        collect the result.

        With ``lazy=True`` the LazyFrame is returned instead (only planning errors are raised here). Raises
        `QueryError` with polars' message for bad SQL, unknown tables or columns. The query reads the dataset
        only: polars' file-reading table functions (`read_csv('/etc/passwd')`, `read_parquet`, ...) are refused
        unless `allow_file_access` (a notebook user joining their own files may want them).
        """
        return run_sql(self, query, lazy=lazy, allow_file_access=allow_file_access)

    # -- boxes, points, the map -------------------------------------------------------------------------------

    def frame_rows(self, frames: Frames) -> pl.LazyFrame:
        """Rows of `frames` for a frames selection: a sample_data token, a list of tokens (in that order;
        UsageError naming any the dataset lacks), or rows of `frames` (used as given)."""
        if isinstance(frames, (pl.DataFrame, pl.LazyFrame)):
            return frames.lazy()
        tokens = [frames] if isinstance(frames, str) else list(frames)
        wanted = pl.DataFrame({"token": tokens}, schema={"token": pl.String}).with_row_index("_order")
        rows = (self.scan("frames").filter(pl.col("token").is_in(tokens)).collect()
                .join(wanted, on="token", how="inner").sort("_order").drop("_order"))
        if rows.height < len(tokens):
            found = set(rows["token"].to_list())
            missing = [t for t in tokens if t not in found]
            raise UsageError(f"no frame (sample_data) {', '.join(map(repr, missing[:5]))}"
                             f"{' ...' if len(missing) > 5 else ''} in {self.root}")
        return rows.lazy()

    def boxes(self, frames: Frames, *, visibility: str = "any", at: str = "sensor") -> pl.DataFrame:
        """The boxes of `frames` (a sample_data token, a list, or rows of `frames`), one row per (frame, box), as the
        devkit gives them: `at="sensor"` is `get_sample_data(token, box_vis_level)` (camera boxes kept by
        `box_in_image` at `visibility` "any" / "all" / "none"; other sensors keep all), `"ego"` the same boxes
        in the ego frame at the frame's time, `"global"` those of `get_boxes` (interpolated for sweeps). See
        `nuparquet.frames.sensor_boxes.boxes_at` for the columns."""
        from nuparquet.frames.sensor_boxes import boxes_at

        return boxes_at(self.frame_rows(frames), self.annotations_in_file_order(), self.scan("tables/sample"),
                        visibility=visibility, at=at)

    def project_boxes(self, frames: Frames, *, visibility: str = "any") -> ProjectedBoxes:
        """The boxes of the camera frames of `frames` in their images (devkit `get_sample_data` + `view_points`,
        `box_in_image` at `visibility`): `nuparquet.frames.projection.project_boxes` with this dataset's
        annotations and samples."""
        from nuparquet.frames.projection import project_boxes

        return project_boxes(self.frame_rows(frames), self.annotations_in_file_order(), self.scan("tables/sample"),
                             visibility=visibility)

    def annotations_in_file_order(self) -> pl.LazyFrame:
        """`annotations` in sample_annotation.json's record order, which is the devkit's `sample['anns']` order
        (the dataset itself is sorted by scene and time): boxes come out in the order the devkit lists them."""
        order = self.scan("tables/sample_annotation").select("token").with_row_index("_file_order")
        return self.scan("annotations").join(order, on="token", how="left").sort("_file_order").drop("_file_order")

    @property
    def source_format(self) -> str:
        """The dataset family converted: "nuscenes" (also Lyft, T4), "nuimages" or "truckscenes"
        (`nuparquet.conversion.formats`)."""
        return self.manifest.get("source", {}).get("format", "nuscenes")

    def masks(self, tokens: str | Sequence[str]):
        """nuImages: the masks of object_ann / surface_ann `tokens` as (N, H, W) uint8 ((H, W) for one token), pixel
        for pixel as the devkit's `mask_decode` (`nuparquet.nuimages.masks.masks`)."""
        from nuparquet.nuimages.masks import masks

        return masks(self, tokens)

    def map(self, location: str) -> MapLayers:
        """The map expansion of `location` (`nuparquet.map.queries.MapLayers`: `layers_on_point`,
        `records_in_patch`, `closest_lane`, `map_mask`, `discretize_lanes`), read once and kept."""
        if location not in self._maps:
            from nuparquet.map.queries import MapLayers

            self._maps[location] = MapLayers.open(self, location)
        return self._maps[location]

    def points(self, tokens: str | Sequence[str] | None = None, *, scene: str | None = None,
               channel: str | None = None, columns: Sequence[str] | None = None) -> np.ndarray | pl.DataFrame:
        """Lidar points from `lidar_points/` (convert --sensors lidar) of sample_data `tokens` (one or a list, in
        that order) or of a `scene` (optionally one lidar `channel`), reading only their row groups.

        Returns (N, 5) float32 [x, y, z, intensity, ring] in the sensor frame, exactly as stored (the devkit's
        `LidarPointCloud.from_file(...).points` is the first 4 columns transposed), column-major (each column
        contiguous; `np.ascontiguousarray` for row-major); with `columns`, a polars DataFrame of those columns
        (e.g. ``["x", "y", "z", "lidarseg_label", "panoptic_label"]``). An unknown scene or channel is a
        UsageError naming the valid ones."""
        from nuparquet.frames import points as frame_points

        self._check_points_selection(scene, channel, "lidar")
        table = frame_points.select_points(self._points_index("lidar_points"), tokens, scene=scene, channel=channel,
                                           columns=columns or list(frame_points.LIDAR_FIELDS))
        return pl.from_arrow(table) if columns else frame_points.lidar_array(table)

    def radar_points(self, tokens: str | Sequence[str] | None = None, *, scene: str | None = None,
                     channel: str | None = None, columns: Sequence[str] | None = None,
                     filtered: bool = False) -> np.ndarray | pl.DataFrame:
        """Radar points from `radar_points/` (convert --sensors radar), selected as `points` selects lidar.

        Returns (N, F) float64 of the PCD fields in header order (the devkit's `RadarPointCloud.points`
        transposed); `filtered=True` keeps only the points the devkit's default filters keep (every point of a file
        without the devkit's 18 fields, to which they do not apply: as the renderers reading such a file keep). With
        `columns`, a polars DataFrame of those columns."""
        from nuparquet.frames import points as frame_points

        self._check_points_selection(scene, channel, "radar")
        index = self._points_index("radar_points")
        fields = frame_points.radar_fields(index)
        wanted = list(columns or fields) + (["passes_default_filters"] if filtered else [])
        table = frame_points.select_points(index, tokens, scene=scene, channel=channel,
                                           columns=list(dict.fromkeys(wanted)))
        if filtered:
            table = table.filter(table.column("passes_default_filters").fill_null(True))
            if not columns or "passes_default_filters" not in columns:
                table = table.drop_columns(["passes_default_filters"])
        return pl.from_arrow(table) if columns else frame_points.radar_array(table, fields)

    def _check_points_selection(self, scene: str | None, channel: str | None, modality: str) -> None:
        if scene is not None:
            self.check_scenes([scene])
        if channel is not None:
            self.check_channel(channel, (modality,))

    def _points_index(self, name: str):
        from nuparquet.frames.points import RowGroupIndex

        if name not in self._entries:
            modality = name.split("_")[0]
            raise UsageError(f"{self.root} has no {name}/: convert with --sensors {modality} to read points")
        if name not in self._row_groups:
            filesystem = self.filesystem[0] if self.is_remote else None
            self._row_groups[name] = RowGroupIndex.read([path for path, _ in self.files(name)], filesystem)
        return self._row_groups[name]


@dataclass(frozen=True)
class DatasetReference:
    """What opens a dataset again elsewhere (an engine worker): picklable and small."""

    root: str
    storage_options: dict | None = None
    dataroot: str | None = None

    def open(self) -> Dataset:
        return open_dataset(self.root, storage_options=self.storage_options, dataroot=self.dataroot)


def open_dataset(path, *, storage_options: Mapping[str, Any] | None = None,
                 dataroot: str | Path | None = None) -> Dataset:
    """Open the nuparquet output directory `path` (local path or URL polars can scan): read and check its
    manifest. `storage_options` (polars' keys, e.g. ``{"aws_endpoint_url": ...}``) serve the manifest and every
    scan; `dataroot` says where the sensor files are when they are not at the dataroot recorded at conversion.

    Raises `FormatError` if `path` does not exist, is not a nuparquet output, or was written in another format
    version.
    """
    root, manifest = load_manifest(path, storage_options)
    return Dataset(root, manifest, storage_options, dataroot)


def as_dataset(dataset, *, storage_options: Mapping[str, Any] | None = None,
               dataroot: str | Path | None = None) -> Dataset:
    """`dataset` itself when it is a `Dataset` (then `storage_options` and `dataroot` must not be given), else the
    output it names opened: what every verb that reads a converted directory accepts."""
    if isinstance(dataset, Dataset):
        if storage_options is not None or dataroot is not None:
            raise TypeError("storage_options and dataroot belong to opening a dataset: pass them to "
                            "nuparquet.open(...), not beside an opened Dataset")
        return dataset
    return open_dataset(dataset, storage_options=storage_options, dataroot=dataroot)
