"""`EmbeddedFiles`: the sensor files an output holds itself (`convert --embed camera,lidar,radar`:
`sensor_files/<modality>/`, one part file per scene), read back byte for byte by sample_data token through the
dataset's own storage (a local folder, or an object store with its `storage_options`, as every scan).

Finding a frame: on first use the `sample_data_token` column of every part file is read once (no bytes) into a
sorted array of (token, part, row group, row): memory is about (token length + 12) bytes per embedded file (~2 MB
for the 41k camera files of v1.0-mini's 10 scenes, ~55 MB for trainval's 1.2M), plus the footers of the last
`OPEN_FILES` part files. A frame's read is then one row group of its scene's file (at most 256 KiB, or the one file
larger than that); the last group read is kept, so a channel read in time order (a video, an MCAP export) reads
each group once.
"""

from __future__ import annotations

import threading

import numpy as np

EMBEDDED_PREFIX = "sensor_files/"
OPEN_FILES = 8  # part files kept open (footers: ~0.5 kB per row group, ~0.5 MB for a trainval scene's images)


def embedded_name(modality: str) -> str:
    """The dataset of `modality`'s embedded files: `sensor_files/camera`, `sensor_files/lidar`, ..."""
    return f"{EMBEDDED_PREFIX}{modality}"


def embedded_modalities(datasets) -> list[str]:
    """The modalities whose files the output with manifest datasets `datasets` embeds."""
    return [name.removeprefix(EMBEDDED_PREFIX) for name in datasets if name.startswith(EMBEDDED_PREFIX)]


class EmbeddedFiles:
    """The embedded files of one modality of an opened dataset."""

    def __init__(self, dataset, modality: str):
        self.dataset = dataset
        self.modality = modality
        self.name = embedded_name(modality)
        self._index: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._paths: list[str] = []
        self._files: dict = {}  # part -> its open pyarrow ParquetFile (pyarrow loads only when files are embedded)
        self._last: tuple[tuple[int, int], list] | None = None  # ((part, group), its bytes as Python objects)
        # a ParquetFile is not safe to read from two threads (the renderers' and the report's): every read of the
        # part files, the index's first build included, holds it (re-entrant: `read` builds the index under it)
        self._lock = threading.RLock()

    def _parquet(self, part: int):
        """The open part file (its footer parsed once while it stays among the `OPEN_FILES` last used)."""
        file = self._files.pop(part, None)
        if file is None:
            import pyarrow.parquet as pq

            filesystem = self.dataset.filesystem
            file = pq.ParquetFile(self._paths[part], filesystem=filesystem[0] if filesystem else None)
        self._files[part] = file  # most recently used last
        while len(self._files) > OPEN_FILES:
            self._files.pop(next(iter(self._files)))
        return file

    def index(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(tokens sorted, part, row group, row in group) of every embedded file (read once)."""
        if self._index is not None:
            return self._index
        with self._lock:
            if self._index is None:
                self._build_index()
        return self._index

    def _build_index(self) -> None:
        if self._index is None:
            self._paths = [path for path, _size in self.dataset.files(self.name)]
            tokens, parts, groups, rows = [], [], [], []
            for part in range(len(self._paths)):
                file = self._parquet(part)
                sizes = [file.metadata.row_group(g).num_rows for g in range(file.metadata.num_row_groups)]
                tokens += file.read(columns=["sample_data_token"]).column(0).to_pylist()
                parts.append(np.full(sum(sizes), part, np.int32))
                groups.append(np.repeat(np.arange(len(sizes), dtype=np.int32), sizes))
                rows.append(np.concatenate([np.arange(n, dtype=np.int32) for n in sizes]) if sizes
                            else np.zeros(0, np.int32))
            keys = np.array(tokens, dtype=bytes) if tokens else np.zeros(0, "S1")
            order = np.argsort(keys, kind="stable")
            join = (lambda arrays: np.concatenate(arrays)[order] if arrays else np.zeros(0, np.int32))
            self._index = (keys[order], join(parts), join(groups), join(rows))

    def __contains__(self, token: str) -> bool:
        return self._find(token) is not None

    def _find(self, token: str) -> int | None:
        keys = self.index()[0]
        key = token.encode()
        at = int(np.searchsorted(keys, key))
        return at if at < len(keys) and keys[at] == key else None

    def read(self, token: str) -> bytes | None:
        """The bytes of sample_data `token`'s file, or None when it is not embedded (its file was missing at
        conversion, or it is not a frame of this modality)."""
        at = self._find(token)
        if at is None:
            return None
        _, parts, groups, rows = self.index()
        where = (int(parts[at]), int(groups[at]))
        with self._lock:
            if self._last is None or self._last[0] != where:
                column = self._parquet(where[0]).read_row_group(where[1], columns=["bytes"]).column(0)
                self._last = (where, column)
            return self._last[1][int(rows[at])].as_py()
