"""Writing the Parquet datasets and the manifest of a conversion (into the hidden sibling of OUT that
`nuparquet.atomic.atomic_directory` renames into place when the conversion is complete)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from nuparquet.format import MANIFEST


def parquet_part_name(index: int) -> str:
    """The file name of part `index` of a dataset: `part-00000.parquet`, ..."""
    return f"part-{index:05d}.parquet"


MAX_ROW_GROUP_ROWS = 65536


class DatasetWriter:
    """Appends tables to `directory/part-{part:05d}.parquet` with one schema (and its file metadata); `group_by` (a column the rows are
    sorted by) starts a new row group at each change of value, so statistics prune e.g. one scene."""

    def __init__(self, directory: Path, schema: pa.Schema, *, group_by: str | None = None, part: int = 0):
        directory.mkdir(parents=True, exist_ok=True)
        self.path = directory / parquet_part_name(part)
        self.schema = schema
        self.group_by = group_by
        self.rows = 0
        self._writer: pq.ParquetWriter | None = None
        self._closed = False

    def write(self, table: pa.Table) -> None:
        if self._writer is None:
            self._writer = self._open(table)
        for start, stop in _row_groups(table, self.group_by):
            self._writer.write_table(table.slice(start, stop - start), row_group_size=MAX_ROW_GROUP_ROWS)
        self.rows += table.num_rows

    def _open(self, first: pa.Table) -> pq.ParquetWriter:
        # Dictionary-encode only repetitive columns (names, channels, locations): for tokens, floats and
        # matrices the dictionary is as large as the data and costs ~40% of the write time.
        repetitive = [f.name for f in self.schema if _is_repetitive(first.column(f.name))]
        return pq.ParquetWriter(self.path, self.schema, compression="zstd", write_statistics=True,
                                use_dictionary=repetitive or False)

    def close(self) -> int:
        """Finish the file (an empty one if nothing was written); returns its size in bytes."""
        if not self._closed:
            if self._writer is None:
                self._writer = self._open(self.schema.empty_table())
            self._writer.close()
            self._closed = True
        return self.path.stat().st_size

    def __enter__(self) -> "DatasetWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


REPETITIVE_SAMPLE_ROWS = 100_000  # rows of the first batch judged (hashing every token of a 2.6M-row table costs ~1 s)


def _is_repetitive(column: pa.ChunkedArray) -> bool:
    """Few distinct values for many rows (judged on the first rows of the first batch written)."""
    if pa.types.is_dictionary(column.type):
        return True
    if not (pa.types.is_string(column.type) or pa.types.is_large_string(column.type) or pa.types.is_string_view(column.type)):
        return False
    sample = column.slice(0, REPETITIVE_SAMPLE_ROWS)
    return len(sample) > 0 and pc.count_distinct(sample).as_py() <= max(1, len(sample) // 10)


def write_parquet(table: pa.Table, directory: Path, *, group_by: str | None = None) -> int:
    """Write `table` as `directory/part-00000.parquet` (see DatasetWriter); returns bytes written."""
    with DatasetWriter(directory, table.schema, group_by=group_by) as writer:
        writer.write(table)
        return writer.close()


def _row_groups(table: pa.Table, group_by: str | None) -> Iterator[tuple[int, int]]:
    n = table.num_rows
    if n == 0:
        yield 0, 0
        return
    if group_by is None:
        yield 0, n
        return
    values = table.column(group_by).to_numpy(zero_copy_only=False)
    starts = np.flatnonzero(values[1:] != values[:-1]) + 1
    bounds = [0, *starts.tolist(), n]
    yield from zip(bounds[:-1], bounds[1:])


def write_manifest(root: Path, manifest: dict) -> None:
    (root / MANIFEST).write_text(json.dumps(manifest, indent=2, sort_keys=False) + "\n")


def utc_now() -> str:
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
