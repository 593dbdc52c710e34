"""GeoParquet 1.1 columns and file metadata for the map datasets.

Geometry is WKB in a `geometry` column; a `bbox` struct column (xmin, ymin, xmax, ymax) is the GeoParquet 1.1
"covering" that lets readers (and polars filters) prune rows and row groups by extent. nuScenes maps are in
local metres from each map's south-west corner, not a registered CRS, so `crs` is null (GeoParquet: unknown);
the corner's WGS 84 position, where known, is in nuparquet's own `nuparquet.map` metadata.
"""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import shapely

GEOPARQUET_VERSION = "1.1.0"
BBOX_TYPE = pa.struct([("xmin", pa.float64()), ("ymin", pa.float64()), ("xmax", pa.float64()), ("ymax", pa.float64())])


def geometry_columns(geometries: np.ndarray) -> tuple[pa.Array, pa.Array]:
    """(R,) shapely geometries (None allowed) -> (WKB binary column, bbox struct column; null where no geometry)."""
    missing = shapely.is_missing(geometries) if len(geometries) else np.zeros(0, bool)
    wkb = shapely.to_wkb(geometries, flavor="iso") if len(geometries) else np.empty(0, object)
    bounds = shapely.bounds(geometries).reshape(-1, 4) if len(geometries) else np.zeros((0, 4))
    empty = missing | (np.isnan(bounds).any(axis=1) if len(bounds) else missing)
    mask = pa.array(empty) if empty.any() else None
    bbox = pa.StructArray.from_arrays([pa.array(bounds[:, k]) for k in range(4)], fields=list(BBOX_TYPE), mask=mask)
    return pa.array(list(wkb), pa.binary()), bbox


def with_geo_metadata(table: pa.Table, extra: dict | None = None, geometries: np.ndarray | None = None) -> pa.Table:
    """`table` (with `geometry` WKB and `bbox` columns) carrying GeoParquet 1.1 `geo` metadata (geometry types
    and bbox computed from the data) and `nuparquet.map` (`extra`). `geometries`: the (R,) shapely geometries of
    the `geometry` column when the caller has them (else parsed back from the WKB)."""
    if geometries is None:
        geometries = shapely.from_wkb(table.column("geometry").to_numpy(zero_copy_only=False))
    present = geometries[~shapely.is_missing(geometries)] if len(geometries) else geometries
    types = sorted({t for t in shapely.get_type_id(present).tolist()}) if len(present) else []
    names = {0: "Point", 1: "LineString", 3: "Polygon", 4: "MultiPoint", 5: "MultiLineString", 6: "MultiPolygon"}
    column = {"encoding": "WKB", "geometry_types": [names[t] for t in types], "crs": None,
              "covering": {"bbox": {k: ["bbox", k] for k in ("xmin", "ymin", "xmax", "ymax")}}}
    if len(present):
        bounds = shapely.total_bounds(present)
        if np.isfinite(bounds).all():
            column["bbox"] = [float(v) for v in bounds]
    metadata = dict(table.schema.metadata or {})
    metadata[b"geo"] = json.dumps({"version": GEOPARQUET_VERSION, "primary_column": "geometry",
                                   "columns": {"geometry": column}}).encode()
    if extra:
        metadata[b"nuparquet.map"] = json.dumps(extra, sort_keys=True).encode()
    return table.replace_schema_metadata(metadata)
