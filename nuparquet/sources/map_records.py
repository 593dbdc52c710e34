"""A converted map expansion file's layers as `json.load` gave them, rebuilt from `map/<layer>` (export-json writes
them back; the devkit's `NuScenesMap` serves them).

The manifest's `files` entry of kind `map_expansion` (one per map) keeps the file's top-level key order, its scalar
values (`version`, `canvas_edge`) and, per layer, the `json_records` facts that make each record come back field for
field: the same key order, bit-identical floats, integers where the JSON had integers.
"""

from __future__ import annotations

import pyarrow as pa
import pyarrow.parquet as pq

from nuparquet.sources.json_records import records_from_columns

KEYED_LAYERS = ("arcline_path_3", "connectivity")  # a JSON object keyed by lane token (the `lane_token` column)


def map_entries(manifest: dict) -> dict[str, dict]:
    """{location: the manifest's files entry of its map expansion file}, in the manifest's order."""
    return {entry["location"]: entry for entry in manifest.get("files", ()) if entry["kind"] == "map_expansion"}


def _layer_table(dataset, layer: str, location: str, columns: list[str] | None = None) -> pa.Table:
    """One location's rows of `map/<layer>` in file order (`columns` only, when given), read by pyarrow (nested
    structs keep their field order), through the dataset's storage (local or remote)."""
    import pyarrow.compute as pc

    filesystem = dataset.filesystem[0] if dataset.is_remote else None
    wanted = None if columns is None else list(dict.fromkeys([*columns, "location"]))
    tables = [pq.ParquetFile(path, filesystem=filesystem).read(columns=wanted)
              for path, _ in dataset.files(f"map/{layer}")]
    if not tables:
        return pa.table({})
    table = pa.concat_tables(tables)
    return table.filter(pc.equal(table.column("location"), location))


def layer_records(dataset, entry: dict, layer: str) -> list[dict] | dict:
    """Layer `layer` of the map file of manifest entry `entry` as `json.load` gave it: a list of records, or for
    `arcline_path_3` / `connectivity` a dict by lane token (the file's order). New objects on every call. Only the
    file's fields are read (not the geometry), column by column."""
    facts = entry["layers"][layer]
    keys = facts["keys"]
    table = _layer_table(dataset, layer, entry["location"], keys + (["lane_token"] if layer in KEYED_LAYERS else []))
    columns = {k: table.column(k).to_pylist() for k in keys}
    records = records_from_columns(columns, table.num_rows, keys, facts.get("json_fields", []),
                                   facts.get("int_values", {}), facts.get("key_orders", {}))
    if layer not in KEYED_LAYERS:
        return records
    lanes = table.column("lane_token").to_pylist()
    if layer == "arcline_path_3":
        return {lane: record["paths"] for lane, record in zip(lanes, records)}
    return dict(zip(lanes, records))


def map_file(dataset, entry: dict) -> dict:
    """The whole map file of `entry`: every top-level key in the file's order (scalars as they were)."""
    return {key: entry["scalars"][key] if key in entry["scalars"] else layer_records(dataset, entry, key)
            for key in entry["top_keys"]}
