"""Sensor point files: lidar `.pcd.bin` (or PCD, TruckScenes), radar PCD v0.7 binary, lidarseg `.bin` and panoptic
`.npz` labels.

Every reader takes a path and returns numpy arrays; a file that cannot be read as its format says raises
`PointFileError` naming the file (the converter turns it into a problem, the renderer into a skipped frame).

- Lidar: little-endian float32 records of `columns` values. The file does not say how many; nuScenes (and the
  devkit's `LidarPointCloud.from_file`) uses 5: x, y, z, intensity, ring index. A size that is not a whole
  number of records is a truncated or foreign file.
- Radar: PCD v0.7 with `DATA binary`; the field names, sizes, types and counts come from the header
  (FIELDS/SIZE/TYPE/COUNT), never from a fixed list. `passes_default_filters` reproduces the devkit's
  `RadarPointCloud.from_file` default filtering.
- Labels: lidarseg `.bin` is one uint8 class index per point; panoptic `.npz` holds `data`, one uint16 per point
  (category index * 1000 + instance id).
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nuparquet.errors import InputError
from nuparquet.sources.point_layout import LIDAR_FIELDS, NUSCENES_LIDAR_COLUMNS  # noqa: F401 - re-exported


# devkit RadarPointCloud default filters (class attributes invalid_states, dynprop_states, ambig_states).
DEFAULT_INVALID_STATES = (0,)
DEFAULT_DYNPROP_STATES = tuple(range(7))
DEFAULT_AMBIG_STATES = (3,)

# PCD TYPE/SIZE -> numpy scalar type (little-endian, as the devkit's struct.unpack with native x86 order).
_PCD_TYPES = {("F", 2): "<f2", ("F", 4): "<f4", ("F", 8): "<f8",
              ("I", 1): "i1", ("I", 2): "<i2", ("I", 4): "<i4", ("I", 8): "<i8",
              ("U", 1): "u1", ("U", 2): "<u2", ("U", 4): "<u4", ("U", 8): "<u8"}
_PCD_KEYS = ("VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA")
_MAX_HEADER_BYTES = 4096


class PointFileError(InputError, ValueError):
    """A sensor or label file that cannot be read as its format says; `path` is the file. (A ValueError too, as
    the lidar reader raised before the sources split.)"""

    def __init__(self, path: str | Path, message: str):
        self.path = str(path)
        self.reason = message
        super().__init__(f"{path}: {message}")


def read_lidar_bin(path: str | Path, columns: int = NUSCENES_LIDAR_COLUMNS) -> np.ndarray:
    """A lidar `.pcd.bin` file.

    Args:
        path: the file (`samples/LIDAR_TOP/*.pcd.bin`, `sweeps/...`).
        columns: float32 values per point (nuScenes: 5 = x, y, z, intensity, ring index).

    Returns:
        (P, columns) float32, exactly as stored; x, y, z in the lidar frame, metres.

    Raises:
        FileNotFoundError: no such file.
        PointFileError: the size is not a whole number of `columns`-float32 records.
    """
    raw = np.fromfile(path, dtype="<f4")
    if raw.size * 4 != Path(path).stat().st_size or raw.size % columns:
        size = Path(path).stat().st_size
        raise PointFileError(path, f"{size} bytes is not a whole number of {columns}-float32 points "
                                   f"({columns * 4} bytes each): truncated, or not a lidar .pcd.bin file")
    return raw.reshape(-1, columns)


@dataclass(frozen=True)
class PcdHeader:
    fields: tuple[str, ...]
    dtype: np.dtype  # one structured record per point, fields named as in FIELDS
    points: int
    data_offset: int  # bytes from the file start to the first point


def read_pcd_header(path: str | Path, head: bytes) -> PcdHeader:
    """Parse the PCD v0.7 header at the start of `head` (the file's first bytes). Raises PointFileError."""
    lines, offset = {}, 0
    while True:
        end = head.find(b"\n", offset)
        if end < 0:
            raise PointFileError(path, "PCD header has no DATA line (not a PCD v0.7 file, or truncated)")
        line = head[offset:end].strip()
        offset = end + 1
        if not line or line.startswith(b"#"):
            continue
        try:
            key, *values = line.decode("ascii").split()
        except UnicodeDecodeError:
            raise PointFileError(path, "PCD header is not ASCII text (not a PCD v0.7 file)") from None
        if key not in _PCD_KEYS:
            raise PointFileError(path, f"unexpected PCD header line {key!r} (expected one of {', '.join(_PCD_KEYS)})")
        lines[key] = values
        if key == "DATA":
            break
    missing = [k for k in ("FIELDS", "SIZE", "TYPE", "WIDTH", "DATA") if k not in lines]
    if missing:
        raise PointFileError(path, f"PCD header lacks {', '.join(missing)}")
    if lines["DATA"] != ["binary"]:
        raise PointFileError(path, f"PCD DATA {' '.join(lines['DATA'])!r} is not supported (only binary)")
    fields, sizes, types = lines["FIELDS"], lines["SIZE"], lines["TYPE"]
    counts = lines.get("COUNT", ["1"] * len(fields))
    if not (len(fields) == len(sizes) == len(types) == len(counts)):
        raise PointFileError(path, f"PCD header has {len(fields)} FIELDS but {len(sizes)} SIZE, {len(types)} TYPE and "
                                   f"{len(counts)} COUNT values")
    if len(set(fields)) != len(fields):
        raise PointFileError(path, f"PCD FIELDS repeat a name: {' '.join(fields)}")
    if any(c != "1" for c in counts):
        raise PointFileError(path, f"PCD COUNT {' '.join(counts)} is not supported (only 1 per field, as the devkit)")
    try:
        formats = [_PCD_TYPES[(t, int(s))] for t, s in zip(types, sizes)]
        width = int(lines["WIDTH"][0])
        height = int(lines.get("HEIGHT", ["1"])[0])
        points = int(lines.get("POINTS", [width * height])[0])
    except (KeyError, ValueError, IndexError):
        raise PointFileError(path, f"PCD SIZE/TYPE {' '.join(sizes)} / {' '.join(types)} or WIDTH/HEIGHT/POINTS "
                                   "is not a supported combination") from None
    if height != 1 or points != width:
        raise PointFileError(path, f"PCD WIDTH {width} HEIGHT {height} POINTS {points}: only unorganised clouds "
                                   "(HEIGHT 1, POINTS = WIDTH) are supported, as the devkit")
    dtype = np.dtype({"names": fields, "formats": formats})  # packed: offsets follow SIZE
    return PcdHeader(tuple(fields), dtype, points, offset)


# A lidar `.pcd` (TruckScenes) holds x, y, z, intensity as float32 and further fields (its per-point `timestamp`): in
# lidar_points and through the sensor reader those keep their names, but a name the points datasets give the frame
# (`timestamp`) takes a `point_` prefix.
LIDAR_PCD_FIELDS = ("x", "y", "z", "intensity")
FRAME_NAMES = ("sample_data_token", "scene_name", "channel", "timestamp", "is_key_frame", "point_index")


def is_pcd(path: str | Path) -> bool:
    """A PCD file (`.pcd`), not nuScenes' raw float32 `.pcd.bin`."""
    return str(path).endswith(".pcd")


def pcd_column(name: str) -> str:
    """The column of a lidar `.pcd` field (see LIDAR_PCD_FIELDS)."""
    return f"point_{name}" if name in FRAME_NAMES else name


def read_lidar_pcd(path: str | Path) -> np.ndarray:
    """A lidar PCD v0.7 binary file (TruckScenes): (P,) structured array as `read_radar_pcd`, whose x, y, z and
    intensity must be float32 (the devkit's `LidarPointCloud` reads them by name).

    Raises:
        FileNotFoundError: no such file.
        PointFileError: not a PCD as `read_radar_pcd` needs, or one of those fields missing or not F 4.
    """
    points = read_radar_pcd(path)
    for name in LIDAR_PCD_FIELDS:
        if name not in points.dtype.names:
            raise PointFileError(path, f"lidar PCD has no field {name!r} (FIELDS {' '.join(points.dtype.names)})")
        if points.dtype[name] != np.dtype("<f4"):
            raise PointFileError(path, f"lidar PCD field {name!r} is {points.dtype[name]}, not float32 (TYPE F SIZE 4)")
    return points


def read_radar_pcd(path: str | Path) -> np.ndarray:
    """A radar PCD v0.7 binary file: (P,) structured array, one field per FIELDS name, typed by SIZE/TYPE.

    Raises:
        FileNotFoundError: no such file.
        PointFileError: an unexpected header, or fewer data bytes than WIDTH points need.
    """
    data = Path(path).read_bytes()
    header = read_pcd_header(path, data[:_MAX_HEADER_BYTES])
    need = header.points * header.dtype.itemsize
    have = len(data) - header.data_offset
    if have < need:
        raise PointFileError(path, f"PCD data is {have} bytes but {header.points} points of {header.dtype.itemsize} "
                                   f"bytes need {need}: truncated")
    return np.frombuffer(data, dtype=header.dtype, count=header.points, offset=header.data_offset)


def passes_default_filters(points: np.ndarray) -> np.ndarray | None:
    """(P,) bool: the points devkit `RadarPointCloud.from_file` keeps with its default filters; None for a PCD
    with fewer than the devkit's 18 fields (the rule does not apply).

    The devkit filters by position, not name: `invalid_state` at -4, `dyn_prop` at 3, `ambig_state` at 11 (their
    names in nuScenes' header). A cloud whose first point has a NaN is empty for the devkit: no point passes.
    """
    names = points.dtype.names
    if len(names) < 18:
        return None
    keep = (np.isin(points[names[-4]], DEFAULT_INVALID_STATES)
            & np.isin(points[names[3]], DEFAULT_DYNPROP_STATES)
            & np.isin(points[names[11]], DEFAULT_AMBIG_STATES))
    if len(points) and _first_point_has_nan(points):
        keep[:] = False
    return keep


def _first_point_has_nan(points: np.ndarray) -> bool:
    first = points[0]
    return any(np.isnan(first[name]) for name in points.dtype.names if points.dtype[name].kind == "f")


def read_lidarseg_bin(path: str | Path) -> np.ndarray:
    """A nuScenes-lidarseg label file: (P,) uint8 class index per lidar point (category.json `index`)."""
    return np.fromfile(path, dtype=np.uint8)


def read_panoptic_npz(path: str | Path) -> np.ndarray:
    """A Panoptic nuScenes label file: (P,) uint16 = category index * 1000 + instance id (0: no instance)."""
    try:
        with np.load(path) as archive:
            if "data" not in archive.files:
                raise PointFileError(path, f"panoptic .npz has no 'data' array (it holds {', '.join(archive.files)})")
            labels = archive["data"]
    except (zipfile.BadZipFile, ValueError, OSError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise PointFileError(path, f"not a readable .npz file ({exc})") from None
    if labels.ndim != 1 or labels.dtype.kind not in "ui":
        raise PointFileError(path, f"panoptic 'data' is {labels.dtype} of shape {labels.shape}, not one integer "
                                   "per point")
    if labels.size and (labels.min() < 0 or labels.max() > np.iinfo(np.uint16).max):
        raise PointFileError(path, "panoptic 'data' holds values outside uint16")
    return labels.astype(np.uint16, copy=False)
