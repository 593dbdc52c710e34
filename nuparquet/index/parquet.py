"""`DIR/infos/`: the v2 infos as Parquet, one row per keyframe sample, the same fields as nested columns
(documented in `schemas/index/infos.json`), so a loader reads one row at a time instead of unpickling the
whole list. Extra columns beside the converter's fields: `split`, and the corrected forms (`*_f64` matrices
before float32 rounding, `velocity_valid`)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pyarrow as pa


def schema_doc() -> dict:
    packaged = resources.files("nuparquet") / "_schemas" / "index" / "infos.json"
    path = Path(str(packaged)) if packaged.is_file() else Path(__file__).resolve().parents[2] / "schemas" / "index" / "infos.json"
    return json.loads(path.read_text())


def _plain(value):
    """numpy scalars -> Python scalars (Arrow infers the same type for every row)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def infos_table(data_list: list[dict], corrected_list: list[dict], split: str) -> pa.Table | None:
    """The split's rows as one Arrow table (None for an empty split: Arrow cannot type empty nested rows)."""
    if not data_list:
        return None
    rows = []
    for entry, fixed in zip(data_list, corrected_list):
        row = _plain(entry)
        row.setdefault("lidar_sweeps", [])
        row["split"] = split
        row["ego2global_f64"] = fixed["ego2global"]
        row["lidar2ego_f64"] = fixed["lidar_points"]["lidar2ego"]
        for inst in row["instances"]:
            inst["velocity_valid"] = bool(np.isfinite(inst["velocity"]).all())
        rows.append(row)
    names = [c["name"] for c in schema_doc()["columns"]]
    table = pa.Table.from_pylist(rows)
    return table.select(names)
