"""`DIR/infos/`: the v2 infos as Parquet, one row per keyframe sample, the same fields as nested columns
(documented in `schemas/index/infos.json`), so a loader reads one row at a time instead of unpickling the
whole list. Extra columns beside the converter's fields: `split`, and the corrected forms (`*_f64` matrices
before float32 rounding, `velocity_valid`)."""

from __future__ import annotations

import json
import math
from importlib import resources
from pathlib import Path

import numpy as np
import pyarrow as pa


def schema_doc() -> dict:
    packaged = resources.files("nuparquet") / "_schemas" / "index" / "infos.json"
    path = Path(str(packaged)) if packaged.is_file() else Path(__file__).resolve().parents[2] / "schemas" / "index" / "infos.json"
    return json.loads(path.read_text())


def infos_table(data_list: list[dict], split: str, ego2global_f64: np.ndarray,
                lidar2ego_f64: np.ndarray) -> pa.Table | None:
    """The split's rows as one Arrow table (None for an empty split: Arrow cannot type empty nested rows).
    `*_f64`: (N, 4, 4) the matrices before float32 rounding, one per entry."""
    if not data_list:
        return None
    rows = []
    for entry, e2g, l2e in zip(data_list, ego2global_f64.tolist(), lidar2ego_f64.tolist()):
        row = dict(entry)
        row.setdefault("lidar_sweeps", [])
        row["instances"] = [inst | {"velocity_valid": math.isfinite(inst["velocity"][0])
                                    and math.isfinite(inst["velocity"][1])} for inst in entry["instances"]]
        row["split"] = split
        row["ego2global_f64"] = e2g
        row["lidar2ego_f64"] = l2e
        rows.append(row)
    names = [c["name"] for c in schema_doc()["columns"]]
    return pa.Table.from_pylist(rows).select(names)
