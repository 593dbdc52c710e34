"""What a typed column cannot hold about each JSON record, kept beside it so `export-json` writes it back exactly.

Real derived datasets are less regular than nuScenes (Lyft Level 5, TIER IV T4): records in another key order,
fields present in some records only (Lyft's lidar rows have no width/height), integers inside float lists
(`"rotation": [1, 0, 0, 0]`), one integer written as a float (`"timestamp": 1535639716773683.0`). The column keeps
the value; two hidden columns of `tables/<name>` keep the rest, only when a table needs them:
- `_layout` (uint16): the record's keys in its own order, as an index into the manifest's `layouts` for the table
  (0 = the table's `key_order`); keys a record lacks are absent from its layout, so they stay absent;
- `_json_types` (list<string>): where the JSON type differs from the column's: `"f"` for a scalar field written
  as an integer in a float column or as a float in an integer column; `"f:iffi"` for a float list whose elements
  marked `i` were written as integers (nested lists flattened row-major).
Both come from the scanner's one pass (`sources/table_scan.py`, `sources/table_typing.py`).
"""

from __future__ import annotations

LAYOUT, JSON_TYPES = "_layout", "_json_types"
HIDDEN = (LAYOUT, JSON_TYPES)


def restore(record: dict, marks: list[str] | None, int_columns: set[str]) -> None:
    """Give `record` (built from the columns) back the JSON types recorded in `marks`."""
    for mark in marks or ():
        name, _, pattern = mark.partition(":")
        value = record.get(name)
        if value is None:
            continue
        if not pattern:
            record[name] = float(value) if name in int_columns else int(value)
            continue
        nested = bool(value) and isinstance(value[0], list)
        flat = [x for row in value for x in row] if nested else list(value)
        flat = [int(x) if flag == "i" else x for x, flag in zip(flat, pattern)]
        if nested:
            width = len(value[0])
            record[name] = [flat[i:i + width] for i in range(0, len(flat), width)]
        else:
            record[name] = flat
