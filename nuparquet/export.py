"""`nuparquet export-json`: write the source tables of a conversion back as nuScenes JSON.

The manifest keeps each table's JSON key order and which integer fields the source stored as JSON
floats, so parsing the output gives records equal field for field to the input: same key order, floats
bit-identical (Python's repr is the shortest round-tripping form), `[]` for null intrinsics, `""` for
empty prev/next.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import pyarrow.parquet as pq

from nuparquet.convert.write import atomic_directory, check_target
from nuparquet.errors import FormatError
from nuparquet.format import MANIFEST
from nuparquet.schemas import table_schemas

BATCH_ROWS = 65536  # records converted to Python at a time: keeps memory flat on trainval


def export_json(dataset_dir: Path | str, out: Path | str, *, overwrite: bool = False,
                on_table: Callable[[str], None] | None = None) -> list[Path]:
    """Write every table of the conversion at `dataset_dir` to `out/<table>.json`; returns the paths."""
    dataset_dir = Path(dataset_dir)
    check_target(out, overwrite=overwrite)
    manifest_path = dataset_dir / MANIFEST
    if not manifest_path.is_file():
        raise FormatError(f"{dataset_dir} is not a nuparquet output (no {MANIFEST})")
    manifest = json.loads(manifest_path.read_text())
    written = []
    with atomic_directory(Path(out), overwrite=overwrite) as tmp:
        for name, info in manifest["tables"].items():
            if on_table:
                on_table(name)
            source = table_schemas()[name].source if name in table_schemas() else f"{name}.json"
            _write_table(dataset_dir / manifest["datasets"][f"tables/{name}"]["path"], tmp / source,
                         info["key_order"], name, set(info.get("json_fields", ())))
            written.append(Path(out) / source)
    return written


def _write_table(parquet_dir: Path, path: Path, key_order: list[str], name: str, json_fields: set[str]) -> None:
    empty_list_fields = {f.name for f in table_schemas()[name].fields if f.empty_list_is_null} \
        if name in table_schemas() else set()
    files = sorted(parquet_dir.glob("*.parquet"))
    with path.open("w") as out:
        out.write("[")
        first = True
        for file in files:
            for batch in pq.ParquetFile(file).iter_batches(batch_size=BATCH_ROWS, columns=key_order):
                columns = [batch.column(k).to_pylist() for k in key_order]
                for key, values in zip(key_order, columns):
                    if key in empty_list_fields:
                        values[:] = [[] if v is None else v for v in values]
                    elif key in json_fields:  # fields the schema does not know, kept as raw JSON text
                        values[:] = [None if v is None else json.loads(v) for v in values]
                for values in zip(*columns):
                    out.write("\n" if first else ",\n")
                    first = False
                    out.write(json.dumps(dict(zip(key_order, values))))
        out.write("\n]\n")
