"""The index files: pickles (one streamed without holding every entry) and the `infos/` Parquet folder, each
written atomically (`nuparquet.atomic`: a hidden partial beside the target, renamed into place when complete)."""

from __future__ import annotations

import io
import pickle
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from nuparquet.atomic import atomic_directory, atomic_file

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
    with atomic_file(path) as partial, open(partial, "wb") as f:
        _Pickler(f, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)


_PROTOCOL = 3  # explicit memo indices (BINPUT): a memo cleared between chunks just overwrites the slots


def _list_body(pickler: _Pickler, buffer: io.BytesIO, items: list) -> bytes:
    """The opcodes that append `items` to the list below them on the unpickler's stack (MARK items APPENDS,
    per batch), pickled with a fresh memo: `items` pickled as a list minus the list's own opcodes."""
    buffer.seek(0)
    buffer.truncate()
    pickler.clear_memo()
    pickler.dump(items)
    data = buffer.getvalue()
    head = b"\x80\x03]q\x00"  # PROTO 3, EMPTY_LIST, BINPUT 0
    if not (data.startswith(head) and data.endswith(b".")):
        raise AssertionError("unexpected pickle layout")
    return data[len(head):-1]


def write_infos_pickle(path: Path, head: dict, key: str, chunks) -> None:
    """Pickle `head | {key: [entries of every chunk]}` (loads equal to pickle.dump of that dict) without
    holding every entry at once: `chunks` yields lists of entries, each pickled with a fresh memo and
    appended to the list in the stream (a trainval split's entries take more memory than the budget)."""
    buffer = io.BytesIO()
    pickler = _Pickler(buffer, protocol=_PROTOCOL)
    with atomic_file(path) as partial, open(partial, "wb") as f:
        f.write(b"\x80\x03}(")  # PROTO 3, EMPTY_DICT, MARK (key/value pairs follow)
        pairs = _list_body(pickler, buffer, [k for item in head.items() for k in item] + [key])
        f.write(pairs[1:-1])  # the pairs and the last key, without their MARK ... APPENDS
        f.write(b"]")  # EMPTY_LIST: the value of `key`
        for chunk in chunks:
            if chunk:
                f.write(_list_body(pickler, buffer, chunk))
        f.write(b"u.")  # SETITEMS, STOP


def write_parquet_dir(directory: Path, tables: dict[str, pa.Table]) -> None:
    """`directory/<name>.parquet` per table, replacing `directory` as a whole once all are written."""
    with atomic_directory(directory, overwrite=True) as partial:
        for name, table in tables.items():
            # small row groups: a loader reading one row decodes ROW_GROUP_ROWS rows, not the split
            pq.write_table(table, partial / f"{name}.parquet", compression="zstd", row_group_size=ROW_GROUP_ROWS)
