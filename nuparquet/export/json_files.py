"""`nuparquet export-json`: write every JSON file a conversion read back, at its path under the dataroot.

The manifest keeps each table's JSON key order and which integer fields the source stored as JSON
floats, so parsing the output gives records equal field for field to the input: same key order, floats
bit-identical (Python's repr is the shortest round-tripping form), `[]` for null intrinsics, `""` for
empty prev/next.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import pyarrow as pa
import pyarrow.parquet as pq

from nuparquet.atomic import atomic_directory, check_target
from nuparquet.atomic import check_apart
from nuparquet.can_bus.files import CanBusFiles
from nuparquet.errors import FormatError
from nuparquet.format import MANIFEST
from nuparquet.progress import OnProgress, Reporter
from nuparquet.sources import json_layout, table_layouts
from nuparquet.sources.json_records import to_records
from nuparquet.sources.map_records import map_file
from nuparquet.schemas import table_schemas

BATCH_ROWS = 65536  # records converted to Python at a time: keeps memory flat on trainval


def export_json(dataset, out: Path | str, *, overwrite: bool = False,
                on_progress: OnProgress | None = None) -> list[Path]:
    """Write every JSON file the conversion `dataset` (a `Dataset`, local or in an object store, or its folder) read
    back under `out`, at its path relative to the dataroot (the tables at `out/<version>/<table>.json`); returns the
    paths written."""
    from nuparquet.dataset import Dataset, open_dataset

    if not isinstance(dataset, Dataset):
        if not (Path(dataset) / MANIFEST).is_file() and "://" not in str(dataset):
            raise FormatError(f"{dataset} is not a nuparquet output (no {MANIFEST})")
        dataset = open_dataset(dataset)  # checks the format and its version, names the file when damaged
    if not dataset.is_remote:
        check_apart(out, dataset.root, what="the converted dataset")
    check_target(out, overwrite=overwrite)
    manifest = dataset.manifest
    files = manifest.get("files") or _files_of_older_manifest(manifest)
    unknown = sorted({f["kind"] for f in files} - set(WRITERS))
    if unknown:
        raise FormatError(f"{dataset.root}: {MANIFEST} lists files of kind {', '.join(unknown)}, which this "
                          f"nuparquet cannot write back (known: {', '.join(WRITERS)}); upgrade nuparquet")
    written = []
    with Reporter(on_progress, "export-json", total=len(files), unit="file") as reporter, \
            atomic_directory(Path(out), overwrite=overwrite) as tmp:
        for entry in files:
            reporter.advance(step=entry["path"])
            target = tmp / entry["path"]
            target.parent.mkdir(parents=True, exist_ok=True)
            WRITERS[entry["kind"]](dataset, manifest, entry, target)
            written.append(Path(out) / entry["path"])
    return written


def _files_of_older_manifest(manifest: dict) -> list[dict]:
    """Outputs written before the manifest listed its files: the tables, under the version folder."""
    version = manifest.get("source", {}).get("version", "")
    if not version:  # the tables' folder: without it they would be written at the filesystem's root ("/sample.json")
        raise FormatError(f"{MANIFEST} lists neither the files converted nor the source version; "
                          "convert the dataroot again with `nuparquet convert --overwrite`")
    return [{"path": f"{version}/{table_schemas()[name].source if name in table_schemas() else name + '.json'}",
             "kind": "table", "dataset": f"tables/{name}"} for name in manifest["tables"]]


def _parquet_files(dataset, name: str) -> list[pq.ParquetFile]:
    """The Parquet files of dataset `name` in order, opened through the dataset's storage (local or remote)."""
    filesystem = dataset.filesystem[0] if dataset.is_remote else None
    return [pq.ParquetFile(path, filesystem=filesystem) for path, _ in dataset.files(name)]


def _arrow_table(dataset, name: str) -> pa.Table:
    """The whole of dataset `name` as read by pyarrow (nested structs keep their field order)."""
    tables = [file.read() for file in _parquet_files(dataset, name)]
    return pa.concat_tables(tables) if tables else pa.table({})


def _write_table_file(dataset, manifest: dict, entry: dict, target: Path) -> None:
    name = entry["dataset"].removeprefix("tables/")
    info = manifest["tables"][name]
    _write_table(_parquet_files(dataset, entry["dataset"]), target, info["key_order"], name,
                 set(info.get("json_fields", ())), info.get("layouts") or [info["key_order"]], entry.get("layout"))


def _write_can_bus_file(dataset, manifest: dict, entry: dict, target: Path) -> None:
    """A CAN bus file (`nuparquet.can_bus.files`), in the source's layout: messages on one line, meta and route
    one value a line (`indent=0`)."""
    content = CanBusFiles(dataset).entry_content(entry)
    target.write_text(json.dumps(content) if entry["kind"] == "can_bus_messages" else json.dumps(content, indent=0))


def _write_inferred_table(dataset, manifest: dict, entry: dict, target: Path) -> None:
    import polars as pl

    rows = pl.from_arrow(_arrow_table(dataset, entry["dataset"])).to_dicts()
    records = to_records(rows, entry["keys"], entry.get("json_fields", []), entry.get("int_values", {}),
                         entry.get("key_orders", {}))
    if "layout" in entry:  # the source's whitespace (sources/json_layout.py): byte for byte
        with target.open("w") as out:
            json_layout.write_array(out, records, entry["layout"])
        return
    target.write_text(json.dumps(records, indent=0))


def _write_map_expansion(dataset, manifest: dict, entry: dict, target: Path) -> None:
    """A map expansion file: every layer in the file's key order, each record as it was (`sources.map_records`)."""
    target.write_text(json.dumps(map_file(dataset, entry)))


# How each kind of converted JSON file is written back (the manifest's "files" name the kind of each).
WRITERS: dict[str, Callable[[object, dict, dict, Path], None]] = {
    "table": _write_table_file,
    "table_inferred": _write_inferred_table,
    "can_bus_messages": _write_can_bus_file,
    "can_bus_meta": _write_can_bus_file,
    "can_bus_route": _write_can_bus_file,
    "map_expansion": _write_map_expansion,
}


def _write_table(files: list[pq.ParquetFile], path: Path, key_order: list[str], name: str, json_fields: set[str],
                 layouts: list[list[str]], layout: dict | None = None) -> None:
    """`files`: the table's Parquet files in order; `layout`: the source's whitespace (`sources.json_layout`; None:
    one record a line)."""
    schema = table_schemas().get(name)
    empty_list_fields = {f.name for f in schema.fields if f.empty_list_is_null} if schema else set()
    shapes = {f.name: f.json_shape for f in schema.fields if f.json_shape} if schema else {}
    opening, separator, closing, empty = json_layout.delimiters(layout)
    with path.open("w") as out:
        first = True
        for parquet in files:
            hidden = [c for c in table_layouts.HIDDEN if c in parquet.schema_arrow.names]
            int_columns = {f.name for f in parquet.schema_arrow if pa.types.is_integer(f.type)}
            for batch in parquet.iter_batches(batch_size=BATCH_ROWS, columns=key_order + hidden):
                columns = [batch.column(k).to_pylist() for k in key_order]
                for key, values in zip(key_order, columns):
                    if key in shapes:  # flat in the column, nested in the JSON
                        width = shapes[key][1]
                        values[:] = [v if v is None else [v[i:i + width] for i in range(0, len(v), width)]
                                     for v in values]
                    if key in empty_list_fields:
                        values[:] = [[] if v is None else v for v in values]
                    elif key in json_fields:  # fields the schema does not know, kept as raw JSON text
                        values[:] = [None if v is None else json.loads(v) for v in values]
                layout_ids = batch.column(table_layouts.LAYOUT).to_pylist() if table_layouts.LAYOUT in hidden else None
                marks = batch.column(table_layouts.JSON_TYPES).to_pylist() if table_layouts.JSON_TYPES in hidden else None
                for i, values in enumerate(zip(*columns)):
                    record = dict(zip(key_order, values))
                    if layout_ids is not None:  # the record's own keys, in its own order; absent stays absent
                        record = {k: record[k] for k in layouts[layout_ids[i]]}
                    if marks is not None and marks[i]:
                        table_layouts.restore(record, marks[i], int_columns)
                    out.write(opening if first else separator)
                    first = False
                    out.write(json_layout.dumps(record, layout))
        out.write(empty if first else closing)
