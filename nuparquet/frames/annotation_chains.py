"""The `prev`/`next` chains of `tables/sample_annotation` as arrays, and the devkit's `PredictHelper._iterate`
walked along them for many agents at once: the one place both the devkit face (`devkit/prediction/helper.py`) and
the prediction evaluation (`evaluation/prediction/`) take an agent's past or future from.

The devkit walks one record at a time; here every agent walks at once, one step of the chain per loop turn (at
most `int(2 * seconds)` turns), with the devkit's rule kept exactly: a step is taken while the last elapsed time
is `<= seconds + BUFFER` and fewer than `int(2 * seconds)` records were kept, and a record is kept when its
elapsed time `|t - t0| / 1e6` is `< seconds + BUFFER`.
"""

from __future__ import annotations

import numpy as np
import polars as pl

MICROSECONDS_PER_SECOND = 1e6
BUFFER = 0.15  # seconds, the devkit's slack on a window's end

NONE = -1  # '' : the chain ends
DANGLING = -2  # a token no record holds: the devkit's `get` raises KeyError on reaching it


def rows_of(tokens: pl.Series, index: pl.DataFrame) -> np.ndarray:
    """(N,) int64 row of each token in `index` (token, row): `NONE` for '', `DANGLING` for an unknown token."""
    rows = (pl.DataFrame({"token": tokens}).join(index, on="token", how="left", maintain_order="left")["row"]
            .to_numpy().astype(np.float64))
    rows = np.where(np.isnan(rows), DANGLING, rows).astype(np.int64)
    return np.where(tokens.to_numpy() == "", NONE, rows)


class AnnotationChains:
    """sample_annotation rows (token, sample_token, instance_token, translation, prev, next, in file order) and
    the samples (token, timestamp) they name, indexed once: each row's prev/next row, its sample's row and time."""

    def __init__(self, annotations: pl.DataFrame, samples: pl.DataFrame):
        n = annotations.height
        self.size = n
        self.tokens = annotations["token"].to_numpy()
        self.sample_tokens = annotations["sample_token"].to_numpy()
        self.instance_tokens = annotations["instance_token"].to_numpy()
        # (N, 3) as stored: the devkit's np.array of the record's list gives these numbers
        self.translation = np.asarray(annotations["translation"].to_numpy(), dtype=np.float64).reshape(n, 3)
        ann_index = pl.DataFrame({"token": annotations["token"], "row": np.arange(n, dtype=np.int64)})
        ann_index = ann_index.unique("token", keep="last", maintain_order=True)  # the devkit's get: the last wins
        self.prev = rows_of(annotations["prev"], ann_index)
        self.next = rows_of(annotations["next"], ann_index)
        self.sample_index = pl.DataFrame({"token": samples["token"],
                                          "row": np.arange(samples.height, dtype=np.int64)})
        self.sample_row = rows_of(annotations["sample_token"], self.sample_index)  # DANGLING when none
        self.sample_timestamp = samples["timestamp"].to_numpy()
        self.timestamp = np.where(self.sample_row >= 0, self.sample_timestamp[np.maximum(self.sample_row, 0)], 0)

    @classmethod
    def of(cls, dataset, *columns: str) -> tuple[AnnotationChains, pl.DataFrame]:
        """The chains of a `Dataset`'s tables, and the annotation rows read (with `columns` besides the chains')."""
        wanted = ["token", "sample_token", "instance_token", "translation", "prev", "next"]
        annotations = dataset.scan("tables/sample_annotation").select(
            wanted + [c for c in columns if c not in wanted]).collect()
        samples = dataset.scan("tables/sample").select("token", "timestamp").collect()
        return cls(annotations, samples), annotations

    def rows_at(self, sample_tokens: list[str], instance_tokens: list[str]) -> np.ndarray:
        """(A,) the row of each (sample, instance) pair, a later record winning as in the devkit's mapping; -1 where
        no annotation has the pair."""
        pairs = pl.DataFrame({"sample_token": self.sample_tokens, "instance_token": self.instance_tokens,
                              "row": np.arange(self.size, dtype=np.int64)},
                             schema={"sample_token": pl.String, "instance_token": pl.String, "row": pl.Int64})
        pairs = pairs.unique(["sample_token", "instance_token"], keep="last")
        asked = pl.DataFrame({"sample_token": sample_tokens, "instance_token": instance_tokens},
                             schema={"sample_token": pl.String, "instance_token": pl.String})
        found = asked.join(pairs, on=["sample_token", "instance_token"], how="left", maintain_order="left")
        return found["row"].fill_null(-1).to_numpy()

    def checked_timestamps(self, rows: np.ndarray) -> np.ndarray:
        if (self.sample_row[rows] == DANGLING).any():
            raise KeyError("sample_annotation names a sample that is not in the sample table")
        return self.timestamp[rows]

    def windows(self, start_rows: np.ndarray, seconds: float, direction: str) -> list[np.ndarray]:
        """The devkit's `_iterate` from each of (A,) start rows: per start, the (L,) rows kept, in walk order
        (`direction` "next": the future, "prev": the past)."""
        if seconds < 0:
            raise ValueError(f"Parameter seconds must be non-negative. Received {seconds}.")
        empty = [np.zeros(0, dtype=np.int64) for _ in start_rows]
        if seconds == 0:
            return empty
        seconds_with_buffer = seconds + BUFFER
        max_annotations = int(2 * seconds)
        step = self.next if direction == "next" else self.prev
        starting_time = self.checked_timestamps(start_rows)
        current = start_rows.copy()
        kept = np.zeros(len(start_rows), dtype=np.int64)
        active = kept < max_annotations
        agents, rows = [], []
        while active.any():
            following = step[current]
            active &= following != NONE
            if (following[active] == DANGLING).any():
                raise KeyError(f"sample_annotation {direction} names no record")
            current = np.where(active, following, current)
            time_elapsed = np.abs(self.checked_timestamps(current) - starting_time) / MICROSECONDS_PER_SECOND
            keep = active & (time_elapsed < seconds_with_buffer)
            agents.append(np.flatnonzero(keep))
            rows.append(current[keep])
            kept += keep
            active &= (time_elapsed <= seconds_with_buffer) & (kept < max_annotations)
        if not agents:
            return empty
        agents, rows = np.concatenate(agents), np.concatenate(rows)
        order = np.argsort(agents, kind="stable")
        return np.split(rows[order], np.cumsum(np.bincount(agents, minlength=len(start_rows)))[:-1])
