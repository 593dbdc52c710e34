"""Open a converted nuparquet directory and query it lazily with polars.

```python
import nuparquet
ds = nuparquet.open("OUT")                        # reads OUT/manifest.json only
lf = ds.scan("annotations")                       # polars.LazyFrame: nothing read until .collect()
ds.sql('SELECT channel, COUNT(*) AS n FROM frames GROUP BY channel')   # polars.DataFrame
```

`path` is a local directory or any URL polars can scan (``s3://bucket/out``, ``gs://…``, ``az://…``,
``https://…``, ``hf://…``). Polars reads the Parquet files itself; the small ``manifest.json`` is read with
fsspec (``pip install fsspec`` plus the filesystem's package, e.g. ``s3fs``), or with the standard library for
``http(s)://`` when fsspec is absent. Pass credentials with ``storage_options=`` (handed to
``polars.scan_parquet`` and to fsspec).

SQL names (`Dataset.sql`): every dataset is registered under its manifest name (``frames``,
``annotations``, ``scenes``, ``instances``, ``"tables/sample"`` — a name with a slash must be double-quoted in
SQL), and each source table also under two plain aliases: ``sample`` and ``tables_sample``. An alias is
skipped if it would shadow a manifest name.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import polars as pl

from nuparquet.errors import FormatError, QueryError, UsageError
from nuparquet.format import FORMAT_NAME, FORMAT_VERSION, MANIFEST



def _is_url(path: str) -> bool:
    return "://" in path and not path.startswith("file://")


def _read_text(url: str, storage_options: Mapping[str, Any] | None) -> str:
    """The text of a small remote file, via fsspec (any filesystem) or urllib (http/https only)."""
    try:
        import fsspec
    except ImportError:
        fsspec = None
    if fsspec is not None:
        with fsspec.open(url, "rt", **dict(storage_options or {})) as f:
            return f.read()
    if url.startswith(("http://", "https://")):
        import urllib.request

        with urllib.request.urlopen(url, timeout=60) as response:  # noqa: S310 - the user's own URL
            return response.read().decode()
    raise FormatError(f"reading {url} needs fsspec (pip install fsspec and the filesystem's package, e.g. s3fs)")


class Dataset:
    """A converted nuparquet directory: its manifest and one lazy polars scan per dataset.

    Attributes: `root` (the path or URL as given, without a trailing slash), `manifest` (the parsed
    manifest.json), `datasets` (names, in manifest order), `dataroot` (the nuScenes dataroot it was converted
    from, as recorded in the manifest), `version` (the source version, e.g. ``v1.0-mini``).
    """

    def __init__(self, root: str, manifest: dict, storage_options: Mapping[str, Any] | None = None):
        self.root = root
        self.manifest = manifest
        self.storage_options = dict(storage_options) if storage_options else None
        self._entries: dict[str, dict] = dict(manifest["datasets"])
        self._channels: dict | None = None
        self._row_groups: dict[str, Any] = {}  # points dataset -> frame_points.RowGroupIndex (footers, read once)

    def __repr__(self) -> str:
        return f"<nuparquet.Dataset {self.root!r} {self.version} datasets={len(self.datasets)}>"

    @property
    def is_remote(self) -> bool:
        return _is_url(self.root)

    @property
    def datasets(self) -> list[str]:
        return list(self._entries)

    @property
    def dataroot(self) -> str | None:
        return self.manifest.get("source", {}).get("dataroot")

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
            self._channels = self._channels_from_data()
        return self._channels

    def _channels_from_data(self) -> dict:
        from nuparquet.channels import channel_facts

        if not {"tables/sensor", "tables/calibrated_sensor"} <= set(self._entries):
            present = (self.scan("frames").select(pl.col("channel").cast(pl.String), pl.col("modality").cast(pl.String))
                       .unique().sort("channel").collect())
            return channel_facts(present["channel"].to_list(), present["modality"].to_list())
        # The sensor table names every channel with its modality; one calibration per channel gives its yaw.
        sensors = self.scan("tables/sensor").select("token", "channel", "modality")
        calibrations = (self.scan("tables/calibrated_sensor").select("sensor_token", "token", "rotation")
                        .join(sensors.select(pl.col("token").alias("sensor_token"), "channel"), on="sensor_token")
                        .sort("channel", "token").unique("channel", keep="first"))
        sensors_df, calibrations_df = pl.collect_all([sensors, calibrations])
        rotations = dict(zip(calibrations_df["channel"].to_list(), calibrations_df["rotation"].to_list()))
        return channel_facts(sensors_df["channel"].to_list(), sensors_df["modality"].to_list(), rotations)

    def _entry(self, name: str) -> dict:
        if name not in self._entries:
            names = sorted(self.datasets, key=lambda n: n.startswith("tables/"))  # derived datasets first
            raise UsageError(f"no dataset {name!r} in {self.root}; valid names: {', '.join(names)}")
        return self._entries[name]

    def location(self, name: str) -> str:
        """The directory (path or URL) of dataset `name`."""
        return f"{self.root}/{self._entry(name).get('path', name)}"

    def scan(self, name: str, **scan_options: Any) -> pl.LazyFrame:
        """A lazy scan of dataset `name` (``"annotations"``, ``"frames"``, ``"tables/sample"``, ...).

        Nothing is read here: polars reads only the columns and row groups the collected query needs
        (row-group statistics prune filters on sorted columns such as ``scene_name``). `scan_options` go to
        `polars.scan_parquet`.
        """
        location = self.location(name)
        if not self.is_remote and not Path(location).is_dir():
            raise FormatError(f"{self.root}: dataset {name!r} is listed in {MANIFEST} but {location} is missing")
        options: dict[str, Any] = {"hive_partitioning": True}
        if self.storage_options:
            options["storage_options"] = self.storage_options
        options.update(scan_options)
        return pl.scan_parquet(f"{location}/**/*.parquet", **options)

    def files(self, name: str) -> list[tuple[str, int]]:
        """The Parquet files of dataset `name` with their sizes in bytes (local directories only)."""
        if self.is_remote:
            raise UsageError("listing files needs a local directory")
        location = Path(self.location(name))
        return [(str(p), p.stat().st_size) for p in sorted(location.rglob("*.parquet"))]

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

    def sql_names(self) -> dict[str, str]:
        """Every SQL name `sql` registers, mapped to the dataset it stands for."""
        names = {name: name for name in self.datasets}
        for name in self.datasets:
            if name.startswith("tables/"):
                table = name.removeprefix("tables/")
                for alias in (table, f"tables_{table}"):
                    names.setdefault(alias, name)
        return names

    def sql_context(self) -> pl.SQLContext:
        """A polars SQLContext with every dataset registered lazily under the names of `sql_names`."""
        context = pl.SQLContext()
        scans = {name: self.scan(name) for name in self.datasets}
        for sql_name, name in self.sql_names().items():
            context.register(sql_name, scans[name])
        return context

    def sql(self, query: str, *, lazy: bool = False, allow_file_access: bool = False) -> pl.DataFrame | pl.LazyFrame:
        """Run polars SQL over every dataset (see the module docstring for the names) and collect the result.

        With ``lazy=True`` the LazyFrame is returned instead (only planning errors are raised here). Raises
        `QueryError` with polars' message for bad SQL, unknown tables or columns. The query reads the dataset
        only: polars' file-reading table functions (`read_csv('/etc/passwd')`, `read_parquet`, ...) are refused
        unless `allow_file_access` (a notebook user joining their own files may want them).
        """
        if not allow_file_access:
            function = _file_reading_function(query)
            if function is not None:
                raise QueryError(f"SQL reads only this dataset: {function}(...) would read another file (pass "
                                 "allow_file_access=True, or --allow-file-access, to allow it)")
        try:
            result = self.sql_context().execute(query, eager=False)
            return result if lazy else result.collect()
        except pl.exceptions.PolarsError as exc:
            message = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            damaged = self.damaged_files() if "parquet" in message.lower() and not self.is_remote else []
            if damaged:
                raise FormatError(f"{damaged[0][0]} is damaged ({damaged[0][1]}); convert the dataset again") from exc
            hint = ""
            lowered = message.lower()
            if "not found" in lowered and ("relation" in lowered or "table" in lowered):
                derived = [n for n in self.datasets if not n.startswith("tables/")]
                tables = [n.removeprefix("tables/") for n in self.datasets if n.startswith("tables/")]
                hint = (f" (datasets: {', '.join(derived)}; source tables: {', '.join(tables)}, "
                        'each also as "tables/<name>" and tables_<name>)')
            raise QueryError(f"SQL failed: {message}{hint}") from exc

    def points(self, tokens: str | list[str] | None = None, *, scene: str | None = None, channel: str | None = None,
               columns: list[str] | None = None):
        """Lidar points from `lidar_points/` (convert --sensors lidar) of sample_data `tokens` (one or a list, in
        that order) or of a `scene` (optionally one `channel`), reading only their row groups.

        Returns (N, 5) float32 [x, y, z, intensity, ring] in the sensor frame, exactly as stored (the devkit's
        `LidarPointCloud.from_file(...).points` is the first 4 columns transposed), column-major (each column
        contiguous; `np.ascontiguousarray` for row-major); with `columns`, a polars
        DataFrame of those columns (e.g. ``["x", "y", "z", "lidarseg_label", "panoptic_label"]``)."""
        from nuparquet.frames import points as frame_points

        table = frame_points.select_points(self._points_index("lidar_points"), tokens, scene=scene, channel=channel,
                                           columns=columns or list(frame_points.LIDAR_ARRAY_COLUMNS))
        return pl.from_arrow(table) if columns else frame_points.lidar_array(table)

    def radar_points(self, tokens: str | list[str] | None = None, *, scene: str | None = None,
                     channel: str | None = None, columns: list[str] | None = None, filtered: bool = False):
        """Radar points from `radar_points/` (convert --sensors radar), selected as `points` selects lidar.

        Returns (N, F) float64 of the PCD fields in header order (the devkit's `RadarPointCloud.points`
        transposed); `filtered=True` keeps only the points the devkit's default filters keep. With `columns`,
        a polars DataFrame of those columns."""
        from nuparquet.frames import points as frame_points

        index = self._points_index("radar_points")
        fields = frame_points.radar_fields(index)
        wanted = list(columns or fields) + (["passes_default_filters"] if filtered else [])
        table = frame_points.select_points(index, tokens, scene=scene, channel=channel, columns=list(dict.fromkeys(wanted)))
        if filtered:
            table = table.filter(table.column("passes_default_filters").fill_null(False))
            if not columns or "passes_default_filters" not in columns:
                table = table.drop_columns(["passes_default_filters"])
        return pl.from_arrow(table) if columns else frame_points.radar_array(table, fields)

    def _points_index(self, name: str):
        from nuparquet.frames.points import RowGroupIndex

        if name not in self._entries:
            modality = name.split("_")[0]
            raise UsageError(f"{self.root} has no {name}/: convert with --sensors {modality} to read points")
        if name not in self._row_groups:
            self._row_groups[name] = RowGroupIndex.read([path for path, _ in self.files(name)])
        return self._row_groups[name]

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


# polars SQL table functions that read files (polars.SQLContext: read_csv, read_parquet, read_json, read_ipc).
_FILE_FUNCTION = re.compile(r"\b(read_(?:csv|parquet|json|ndjson|ipc|delta|excel|avro))\s*\(", re.IGNORECASE)
_SQL_STRING = re.compile(r"'(?:[^']|'')*'|\"(?:[^\"]|\"\")*\"")


def _file_reading_function(query: str) -> str | None:
    """The first file-reading table function called in `query` (string literals and quoted names ignored)."""
    match = _FILE_FUNCTION.search(_SQL_STRING.sub("''", query))
    return match.group(1) if match else None


def _check_manifest(manifest: Any, where: str) -> dict:
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT_NAME:
        raise FormatError(f"{where}: not a nuparquet output ({MANIFEST} does not say \"format\": \"{FORMAT_NAME}\")")
    version = manifest.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int):  # JSON true is a Python int
        raise FormatError(f"{where}: {MANIFEST} has no integer format_version")
    if version > FORMAT_VERSION:
        raise FormatError(
            f"{where}: written in nuparquet format {version}, newer than this nuparquet reads ({FORMAT_VERSION}); "
            "upgrade nuparquet")
    if version < FORMAT_VERSION:
        raise FormatError(
            f"{where}: written in nuparquet format {version}, older than this nuparquet reads ({FORMAT_VERSION}); "
            "convert the dataroot again with `nuparquet convert --overwrite`")
    if not isinstance(manifest.get("datasets"), dict) or not manifest["datasets"]:
        raise FormatError(f"{where}: {MANIFEST} lists no datasets")
    return manifest


def open_dataset(path: str | os.PathLike, *, storage_options: Mapping[str, Any] | None = None) -> Dataset:
    """Open the nuparquet output directory `path` (local path or URL): read and check its manifest.

    Raises `FormatError` if `path` does not exist, is not a nuparquet output, or was written in another
    format version.
    """
    text_path = os.fspath(path)
    if _is_url(text_path):
        root = text_path.rstrip("/")
        try:
            text = _read_text(f"{root}/{MANIFEST}", storage_options)
        except FormatError:
            raise
        except (OSError, ValueError) as exc:  # FileNotFoundError, HTTPError, ... from fsspec or urllib
            raise FormatError(f"{root}: cannot read {MANIFEST} ({exc}); not a nuparquet output?") from exc
    else:
        local = Path(text_path.removeprefix("file://")).expanduser()
        if not local.exists():
            raise FormatError(f"{local}: no such directory")
        if not local.is_dir():
            raise FormatError(f"{local}: not a directory (expected a nuparquet output directory)")
        if not (local / MANIFEST).is_file():
            raise FormatError(f"{local}: not a nuparquet output (no {MANIFEST}; create one with `nuparquet convert`)")
        root = str(local.resolve())
        try:
            text = (local / MANIFEST).read_text()
        except (UnicodeDecodeError, OSError) as exc:
            raise FormatError(f"{root}: {MANIFEST} cannot be read as text ({exc.__class__.__name__}); "
                              "the output is damaged: convert again") from exc
    try:
        manifest = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(f"{root}: {MANIFEST} is not valid JSON ({exc})") from exc
    return Dataset(root, _check_manifest(manifest, root), storage_options)
