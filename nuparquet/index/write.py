"""Atomic output: every file goes to a hidden sibling first and is renamed into place when complete."""

from __future__ import annotations

import os
import pickle
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq


ROW_GROUP_ROWS = 256


class _Pickler(pickle.Pickler):
    """numpy's own reduction of a float64/int64 scalar (its dtype and raw bytes through
    `numpy._core.multiarray.scalar`) costs ~3x what pickling the rest of an info does; `numpy.float64(x)`
    unpickles to the same object (type and value) and exists under that name in numpy 1.x and 2.x."""

    def reducer_override(self, obj):
        kind = type(obj)
        if kind is np.float64:
            return np.float64, (float(obj),)
        if kind is np.int64:
            return np.int64, (int(obj),)
        return NotImplemented


def write_pickle(path: Path, obj) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            _Pickler(f, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_parquet_dir(directory: Path, tables: dict[str, pa.Table]) -> None:
    """`directory/<name>.parquet` per table, replacing `directory` as a whole once all are written."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{directory.name}.tmp-", dir=directory.parent))
    try:
        for name, table in tables.items():
            # small row groups: a loader reading one row decodes ROW_GROUP_ROWS rows, not the split
            pq.write_table(table, tmp / f"{name}.parquet", compression="zstd", row_group_size=ROW_GROUP_ROWS)
        old = directory.with_name(f".{directory.name}.old-{os.getpid()}")
        if directory.exists():
            os.replace(directory, old)
        os.replace(tmp, directory)
        shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
