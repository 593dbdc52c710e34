"""Scene shards of a `Samples` and its iterable form: a seeded, deterministic stream over one rank's (and one
data-loader worker's) scenes that resumes at the same next sample from its `state_dict()`.

Every scene goes to exactly one rank, and within a rank to exactly one worker: the scenes, largest first (ties in
scene order), each to the part holding the fewest samples so far (ties to the lowest part). More parts than scenes
leave some parts empty.
"""

from __future__ import annotations

import copy
import os

import numpy as np


def scene_parts(scene: np.ndarray, parts: int) -> list[np.ndarray]:
    """For `scene` (S,) (the scene of each sample) the positions (sorted) of the samples of each of `parts` parts,
    whole scenes balanced by sample count."""
    if parts < 1:
        raise ValueError(f"parts must be at least 1, not {parts}")
    scenes, first, counts = np.unique(scene, return_index=True, return_counts=True)
    order = np.lexsort((first, -counts))  # largest first, then in the order the scenes come
    load = np.zeros(parts, dtype=np.int64)
    owner = np.empty(len(scenes), dtype=np.int64)
    for k in order:
        owner[k] = int(np.argmin(load))
        load[owner[k]] += counts[k]
    of_sample = owner[np.searchsorted(scenes, scene)]
    return [np.flatnonzero(of_sample == p) for p in range(parts)]


def shard(samples, rank: int, world_size: int):
    """A copy of `samples` serving only rank `rank` of `world_size`'s scenes (`Samples.shard`)."""
    if not 0 <= rank < world_size:
        raise ValueError(f"rank {rank} is not in [0, {world_size})")
    part = copy.copy(samples)
    part.indices = samples.indices[scene_parts(samples.scene[samples.indices], world_size)[rank]]
    return part


class SampleStream:
    """The samples of `samples` (a `Samples` or one of its shards) as an iterable: each epoch the scenes in a seeded
    random order and, unless `sequential` (temporal training: each scene's samples in time order), the samples
    shuffled too; without `shuffle`, the `Samples` order. The order depends on (seed, epoch, worker) only.

    `state_dict()` / `load_state_dict(state)` carry (seed, epoch, worker, position): a stream loaded with the state
    of an interrupted one yields the same remaining samples. In a data-loader worker, `select_worker(id, n)` (what
    `worker_init_fn` calls) keeps that worker's scenes. Pickles as small as the `Samples`; no dataset is opened
    until the first item is read.
    """

    def __init__(self, samples, *, seed: int = 0, shuffle: bool = True, sequential: bool = False) -> None:
        self.samples = samples
        self.seed, self.shuffle, self.sequential = seed, shuffle, sequential
        self.epoch = 0
        self.worker = (0, 1)
        self.position = 0  # samples of this epoch already yielded

    def set_epoch(self, epoch: int) -> None:
        self.epoch, self.position = epoch, 0

    def select_worker(self, worker_id: int, num_workers: int) -> None:
        if not 0 <= worker_id < num_workers:
            raise ValueError(f"worker {worker_id} is not in [0, {num_workers})")
        self.worker = (worker_id, num_workers)

    def order(self) -> np.ndarray:
        """The positions into `samples` this worker yields this epoch, in order."""
        worker_id, num_workers = self.worker
        scene = self.samples.scene[self.samples.indices]
        mine = scene_parts(scene, num_workers)[worker_id]
        if not self.shuffle:
            return mine
        rng = np.random.default_rng([self.seed, self.epoch, worker_id])
        scenes = np.unique(scene[mine])
        rank_of = np.empty(len(scenes), dtype=np.int64)
        rank_of[rng.permutation(len(scenes))] = np.arange(len(scenes))
        mine = mine[np.argsort(rank_of[np.searchsorted(scenes, scene[mine])], kind="stable")]
        return mine if self.sequential else mine[rng.permutation(len(mine))]

    def __len__(self) -> int:
        return len(self.order())

    def __iter__(self):
        order = self.order()
        while self.position < len(order):
            position = int(order[self.position])
            self.position += 1
            yield self.samples[position]
        self.position = 0
        self.epoch += 1

    def state_dict(self) -> dict:
        return {"seed": self.seed, "epoch": self.epoch, "worker": list(self.worker), "position": self.position}

    def load_state_dict(self, state: dict) -> None:
        self.seed, self.epoch, self.position = state["seed"], state["epoch"], state["position"]
        self.worker = tuple(state["worker"])


_forked = False  # this process was forked (a DataLoader or Pool worker): polars' thread pool did not come along


def _after_fork() -> None:
    global _forked
    _forked = True


os.register_at_fork(after_in_child=_after_fork)


def check_worker(samples) -> None:
    """UsageError in a forked process asked for a part that computes with polars per item (radar, the devkit's
    sweeps, the BEV map): polars' thread pool does not survive a fork, and such a read would hang forever. The
    default parts read with pyarrow and numpy only."""
    if not _forked:
        return
    parts = [name for name, wanted in (("radars", bool(samples.radars)), ("sweeps_as='devkit'",
             samples.sweeps_as == "devkit"), ("bev_map", bool(samples.bev_classes))) if wanted]
    if parts:
        from nuparquet.errors import UsageError

        raise UsageError(f"Samples with {', '.join(parts)} cannot be read in a forked worker (polars' thread pool "
                         "does not survive a fork): use DataLoader(..., multiprocessing_context='spawn')")


def worker_init_fn(worker_id: int) -> None:
    """A `DataLoader(worker_init_fn=...)`: the worker's copy of the `SampleStream` keeps that worker's scenes
    (torch imported here only, inside a torch worker)."""
    from torch.utils.data import get_worker_info

    info = get_worker_info()
    info.dataset.select_worker(info.id, info.num_workers)
