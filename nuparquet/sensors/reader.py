"""`SensorReader`: where a dataset's sensor data is read from, decided in one place for every caller (scene renders
and their bird's-eye view, single pictures, sweeps, the MCAP export, the report, the devkit skin, the training
loader).

A frame's points come from the converted datasets (`lidar_points/`, `radar_points/`, read through the dataset's own
storage: a local folder or an object store with its `storage_options`) when the frame is there, else from its
file under the dataroot (`Dataset.dataroot`: the one given when opening, else the one recorded at conversion);
ground-truth labels from `lidar_points/` or the label file `tables/lidarseg` / `tables/panoptic` names; images
from their files. A file the output embeds (`convert --embed camera,lidar,radar`: `sensor_files/<modality>/`,
`nuparquet.sensors.embedded`) is read from there, through the same storage, before the dataroot is looked at: such
an output serves its sensors with no dataroot at all, from a folder or an object store. When a frame's data is in
none of these places the error says so once, the same way for every caller (`MissingSensorData`, which is also a
FileNotFoundError for the renderers that skip such frames); an object-store output is never read against the local
dataroot recorded at conversion (UsageError naming what is not embedded and the `--embed` flag), only against one
given when opening.

```python
reader = ds.sensors
xyzi, labels = reader.lidar(token, filename, labels="lidarseg")     # (P, 4) float32, (P,) int64
frame = reader.points(token, filename, "radar")                     # a polars DataFrame of the PCD fields
jpeg = reader.file_bytes(token, filename, "camera")                 # the file's bytes (embedded, else the file)
```
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import InputError, UsageError
from nuparquet.sensors.embedded import EmbeddedFiles, embedded_modalities, embedded_name
from nuparquet.sources.points import LIDAR_FIELDS

POINTS_DATASETS = {"lidar": "lidar_points", "radar": "radar_points"}
LABEL_COLUMNS = {"lidarseg": "lidarseg_label", "panoptic": "panoptic_label"}
XYZI = ("x", "y", "z", "intensity")


def inside(root: Path, filename: str) -> Path | None:
    """`root / filename`, or None for a filename that leaves the dataroot ("../..", an absolute path): the one rule for
    every sensor file a dataset names."""
    relative = Path(filename)
    if relative.is_absolute() or ".." in relative.parts:
        return None
    return root / relative


class MissingSensorData(InputError, FileNotFoundError):
    """A frame's data is neither in the converted datasets nor in a file under the dataroot; `path` is the file
    looked for."""

    def __init__(self, path: str, message: str):
        self.path = str(path)
        self.reason = message
        InputError.__init__(self, message)

    def __str__(self) -> str:
        return self.reason

    def __reduce__(self):  # a DataLoader worker's exception is pickled to the main process: rebuilt whole there
        return type(self), (self.path, self.reason)


class SensorReader:
    """The sensor data of one opened dataset (`ds.sensors`)."""

    def __init__(self, dataset) -> None:
        self.dataset = dataset
        self._columns: dict[str, list[str]] = {}
        self._label_files: dict[str, dict[str, str]] = {}
        self._embedded: dict[str, EmbeddedFiles | None] = {}

    # -- where the files are ---------------------------------------------------------------------------------------

    def root(self, what: str = "the sensor files", *, otherwise: str = "") -> Path:
        """The local dataroot holding the sensor files: UsageError saying `what` is read from it when it is not
        there (`otherwise`: what else the user may do, e.g. ", or --no-videos")."""
        if self.dataset.is_remote and not self.dataset.dataroot_given:  # never the recorded local dataroot
            embedded = embedded_modalities(self.dataset.datasets)
            raise UsageError(f"{self.dataset.root} is on object storage and does not hold {what} (it embeds "
                             f"{', '.join(embedded) or 'no sensor files'}): convert with --embed camera,lidar,radar "
                             "(those needed) to store the sensor files in the output, or give the local dataroot: "
                             "--dataroot PATH (in Python nuparquet.open(URL, storage_options=..., dataroot=...))"
                             f"{otherwise}")
        dataroot = self.dataset.dataroot
        root = Path(dataroot) if dataroot else None
        if root is None or not root.is_dir():
            raise UsageError(f"the dataroot {root} (where {what} are read from) does not exist; pass --dataroot PATH "
                             f"(the folder holding samples/ and sweeps/; in Python nuparquet.open(OUT, dataroot=...))"
                             f"{otherwise}")
        return root

    def path(self, filename: str, root: Path | None = None) -> Path:
        """The file of a sample_data `filename` under the dataroot; one that leaves it ("../..", an absolute path)
        is refused (InputError naming it)."""
        path = inside(root if root is not None else self.root(), filename)
        if path is None:
            raise InputError(f"{filename}: outside the dataroot, refused")
        return path

    # -- points ------------------------------------------------------------------------------------------------------

    def converted_columns(self, modality: str) -> list[str]:
        """The columns of `lidar_points/` or `radar_points/` ([] when not converted)."""
        name = POINTS_DATASETS[modality]
        if name not in self._columns:
            self._columns[name] = (self.dataset.scan(name).collect_schema().names()
                                   if name in self.dataset.datasets else [])
        return self._columns[name]

    def converted(self, token: str, modality: str, columns) -> pl.DataFrame | None:
        """The frame's rows of `columns` in the points dataset of `modality`, or None when the frame is not there
        (not converted, a sweep left out, its file missing at conversion)."""
        have = self.converted_columns(modality)
        if not have:
            return None
        from nuparquet.frames.points import FramesNotConverted  # pyarrow: only when points are converted

        read = self.dataset.points if modality == "lidar" else self.dataset.radar_points
        try:  # only columns the dataset has: an unknown column must not read as "frame not converted"
            return read(token, columns=[c for c in columns if c in have])
        except FramesNotConverted:  # the frame is not there (every other error is the storage's, and raised)
            return None

    def points(self, token: str, filename: str, modality: str, columns=None) -> pl.DataFrame:
        """One frame's points as a polars DataFrame: from the converted dataset when the frame is there (`columns`,
        default every sensor field the dataset has), else from its file (lidar: x, y, z, intensity, ring, or a
        lidar `.pcd`'s fields as lidar_points names them (TruckScenes: x, y, z, intensity, point_timestamp);
        radar: the PCD fields; `columns` that a file does not hold, such as labels, left out).

        Raises:
            MissingSensorData: neither converted nor a file under the dataroot.
            PointFileError: a file that cannot be read as its format says.
        """
        if columns is None:
            columns = self.sensor_fields(modality)
        frame = self.converted(token, modality, columns)
        if frame is not None:
            return frame
        from nuparquet.sources.points import (
            is_pcd, lidar_from_bytes, lidar_pcd_from_bytes, pcd_column, radar_from_bytes,
        )

        data, source = self.file_bytes(token, filename, modality, where=True)  # embedded, else the file
        if modality == "lidar" and is_pcd(filename):  # TruckScenes: a PCD, named as lidar_points names its fields
            records = lidar_pcd_from_bytes(source, data)
            frame = pl.DataFrame({pcd_column(name): records[name] for name in records.dtype.names})
        elif modality == "lidar":
            values = lidar_from_bytes(source, data, len(LIDAR_FIELDS))
            frame = pl.DataFrame({name: values[:, j] for j, name in enumerate(LIDAR_FIELDS)})
        else:
            records = radar_from_bytes(source, data)
            frame = pl.DataFrame({name: records[name] for name in records.dtype.names})
        if columns is None:
            return frame
        # built from the columns, not `select`ed: polars' thread pool is not there in a forked training worker
        return pl.DataFrame([frame.get_column(c) for c in columns if c in frame.columns])

    def sensor_fields(self, modality: str) -> list[str] | None:
        """The sensor fields of a frame of `modality` as the converted dataset stores them (lidar: x, y, z,
        intensity, ring and the labels; radar: the PCD fields), or, when not converted, the lidar file's; None for
        a radar not converted (every field its PCD file holds)."""
        from nuparquet.frames.points import FRAME_COLUMNS

        converted = [c for c in self.converted_columns(modality)
                     if c not in FRAME_COLUMNS and c != "passes_default_filters"]
        return converted or (list(LIDAR_FIELDS) if modality == "lidar" else None)

    def lidar(self, token: str, filename: str, *, labels: str | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """(P, 4) float32 x, y, z, intensity of a lidar frame as the devkit's `LidarPointCloud.from_file` loads them
        (every point, the sensor frame) and, for `labels` ("lidarseg" or "panoptic"), its (P,) int64 ground-truth
        labels (from `lidar_points/` or the label file `tables/<labels>` names; UsageError when it has none)."""
        column = LABEL_COLUMNS.get(labels) if labels else None
        wanted = [*XYZI, *([column] if column and column in self.converted_columns("lidar") else [])]
        frame = self.points(token, filename, "lidar", wanted)
        points = frame.select(XYZI).to_numpy().astype(np.float32)
        if not labels:
            return points, None
        if column in frame.columns and frame[column].null_count() == 0:
            found = frame[column].to_numpy().astype(np.int64)
        else:
            found = self.label_file(token, labels)
        if len(found) != len(points):
            raise InputError(f"{labels} labels of sample_data {token} hold {len(found)} labels for {len(points)} "
                             "points")
        return points, found

    def labels(self, token: str, labels: str) -> np.ndarray:
        """(P,) int64: the "lidarseg" or "panoptic" ground-truth labels of lidar frame `token` alone (without its
        points): from `lidar_points/` when the frame is there with them, else the label file."""
        column = LABEL_COLUMNS[labels]
        if column in self.converted_columns("lidar"):
            frame = self.converted(token, "lidar", [column])
            if frame is not None and frame[column].null_count() == 0:
                return frame[column].to_numpy().astype(np.int64)
        return self.label_file(token, labels)

    def label_file(self, token: str, labels: str) -> np.ndarray:
        """(P,) int64: the lidarseg or panoptic label file `tables/<labels>` names for sample_data `token`."""
        from nuparquet.frames.sweeps import read_point_file
        from nuparquet.sources.points import read_lidarseg_bin, read_panoptic_npz

        if f"tables/{labels}" not in self.dataset.datasets:
            raise UsageError(f"{self.dataset.root} has no {labels} labels (the dataroot had no {labels}.json when "
                             "converted)")
        if labels not in self._label_files:  # one read of the small index table, not a query per frame
            table = self.dataset.scan(f"tables/{labels}").select("sample_data_token", "filename").collect()
            pairs = zip(table["sample_data_token"].to_list(), table["filename"].to_list())
            self._label_files[labels] = dict(reversed(list(pairs)))  # a token listed twice: its first file
        filename = self._label_files[labels].get(token)
        if filename is None:
            raise UsageError(f"sample_data {token} has no {labels} labels (only lidar keyframes have them)")
        reader = read_panoptic_npz if labels == "panoptic" else read_lidarseg_bin
        return read_point_file(reader, self.path(filename)).astype(np.int64)

    def file(self, token: str, filename: str, modality: str) -> Path:
        """The frame's file under the dataroot, which must exist: MissingSensorData saying where the data was looked
        for (UsageError for an object-store output given no dataroot: `root`)."""
        what = f"the {modality} {'images' if modality == 'camera' else 'points'}"
        kind = "image" if modality == "camera" else "point"
        embedded = self.embedded(modality)
        embeds = embedded_modalities(self.dataset.datasets)
        hint = "" if self.dataset.is_remote else (f"; or convert with --embed {modality} to store them in the output "
                                                  f"(it embeds {', '.join(embeds) or 'no sensor files'})")
        try:
            root = self.root(f"{what} (of sample_data {token})", otherwise=hint)
        except UsageError:
            if embedded is None:
                raise
            raise MissingSensorData(filename, f"missing {kind} file: {filename} ({what} of sample_data {token}: not "
                                              f"in {embedded.name}/, its file was missing at conversion; and no "
                                              "dataroot: --dataroot PATH where the files are)") from None
        path = self.path(filename, root)
        if not path.is_file():
            where = []
            if modality in POINTS_DATASETS:
                where.append(f"not in {POINTS_DATASETS[modality]}/" if self.converted_columns(modality) else
                             f"not converted: convert --sensors {modality}")
            where.append(f"not in {embedded_name(modality)}/" if embedded is not None else
                         f"not embedded: convert --embed {modality}")
            raise MissingSensorData(str(path), f"missing {kind} file: {path} ({what} of sample_data {token}, "
                                               f"{', '.join(where)}; or --dataroot PATH where the files are)")
        return path

    # -- the files' bytes --------------------------------------------------------------------------------------------

    def embedded(self, modality: str) -> EmbeddedFiles | None:
        """The files of `modality` the output embeds (`sensor_files/<modality>/`), or None when it embeds none."""
        if modality not in self._embedded:
            name = embedded_name(modality)
            self._embedded[modality] = EmbeddedFiles(self.dataset, modality) if name in self.dataset.datasets else None
        return self._embedded[modality]

    def file_bytes(self, token: str, filename: str, modality: str, *, where: bool = False):
        """The bytes of sample_data `token`'s file (`modality`: "camera", "lidar" or "radar"): embedded in the
        output when it is there, else read from `filename` under the dataroot. With `where`: (bytes, where they
        came from, for error messages).

        Raises:
            MissingSensorData: neither embedded nor a file under the dataroot.
            UsageError: an object-store output that does not embed it, opened without a dataroot.
        """
        embedded = self.embedded(modality)
        data = embedded.read(token) if embedded is not None else None
        if data is not None:
            return (data, f"{self.dataset.root}/{embedded.name} {filename}") if where else data
        path = self.file(token, filename, modality)
        data = path.read_bytes()
        return (data, str(path)) if where else data

    def file_size(self, token: str, filename: str, modality: str) -> int:
        """Bytes of the frame's file (embedded, else under the dataroot); 0 when it is in neither place."""
        embedded = self.embedded(modality)
        data = embedded.read(token) if embedded is not None else None
        if data is not None:
            return len(data)
        try:
            return self.path(filename).stat().st_size
        except (OSError, InputError, UsageError):
            return 0

    def embeds(self, *modalities: str) -> bool:
        """The output embeds the files of every one of `modalities`."""
        return all(self.embedded(m) is not None for m in modalities)
