"""Scene shards and the seeded stream: every sample exactly once across ranks x workers (world sizes 1, 2, 3 and
more ranks than scenes), whole scenes per part, balance, determinism, resume at the same next sample, the
worker_init_fn's split, and a small pickle. The stream is checked on sample tokens (no sensor data read)."""

from __future__ import annotations

import pickle
import sys
import types
from collections import Counter

import numpy as np
import pytest

from nuparquet.training.samples import Samples
from nuparquet.training.shards import scene_parts, worker_init_fn


@pytest.fixture(scope="session")
def token_samples(synth_out) -> Samples:
    """The synth train split (2 scenes x 6 samples) without sensor data: items are tokens and boxes only."""
    return Samples(synth_out, "train", lidar=False, cameras=(), sweeps=0, version="v1.0-trainval")


def _tokens(stream) -> list[str]:
    return [item["sample_token"] for item in stream]


@pytest.mark.parametrize("world_size", [1, 2, 3, 5])
@pytest.mark.parametrize("num_workers", [1, 2])
def test_every_sample_once_across_ranks_and_workers(token_samples, world_size, num_workers):
    seen, scene_owner = [], {}
    for rank in range(world_size):
        part = token_samples.shard(rank, world_size)
        for worker in range(num_workers):
            stream = part.stream(seed=3)
            stream.select_worker(worker, num_workers)
            items = list(stream)
            seen += [item["sample_token"] for item in items]
            for item in items:  # whole scenes: each scene's samples all on one (rank, worker)
                assert scene_owner.setdefault(item["scene_token"], (rank, worker)) == (rank, worker)
    assert Counter(seen) == Counter(token_samples.sample_token.tolist())
    assert len(scene_owner) == 2


def test_scene_parts_balance_whole_scenes_and_leave_extra_parts_empty():
    scene = np.array([0, 0, 0, 0, 1, 1, 2, 2, 2, 3])  # 4 scenes of 4, 2, 3, 1 samples
    parts = scene_parts(scene, 2)
    assert [sorted(set(scene[p].tolist())) for p in parts] == [[0, 3], [1, 2]]  # 4+1 and 3+2 samples
    assert sorted(np.concatenate(parts).tolist()) == list(range(len(scene)))
    many = scene_parts(scene, 6)
    assert [len(p) for p in many] == [4, 3, 2, 1, 0, 0]


def test_a_shard_holds_whole_scenes(token_samples):
    a, b = token_samples.shard(0, 2), token_samples.shard(1, 2)
    assert len(a) == len(b) == 6  # the two 6-sample scenes, one per rank
    assert len(set(a.scene[a.indices].tolist())) == 1 and set(a.scene[a.indices]) != set(b.scene[b.indices])
    assert len(token_samples.shard(4, 5)) == 0 and list(token_samples.shard(4, 5).stream()) == []


def test_the_order_is_seeded_and_changes_with_the_epoch(token_samples):
    first = _tokens(token_samples.stream(seed=1))
    assert first == _tokens(token_samples.stream(seed=1))
    assert first != token_samples.sample_token.tolist()  # shuffled
    stream = token_samples.stream(seed=1)
    stream.set_epoch(1)
    assert sorted(_tokens(stream)) == sorted(first) and _tokens(token_samples.stream(seed=1)) == first
    assert _tokens(token_samples.stream(shuffle=False)) == token_samples.sample_token.tolist()


def test_sequential_mode_keeps_each_scene_in_time_order(token_samples):
    items = list(token_samples.stream(seed=5, sequential=True))
    for scene in set(token_samples.scene_token.tolist()):
        times = [it["timestamp_us"] for it in items if it["scene_token"] == scene]
        assert times == sorted(times)
    scenes = [it["scene_token"] for it in items]
    assert scenes == sorted(scenes, key=scenes.index)  # contiguous per scene


def test_resume_yields_the_same_remaining_samples(token_samples):
    full = _tokens(token_samples.stream(seed=7))
    stream = token_samples.stream(seed=7)
    iterator = iter(stream)
    head = [next(iterator)["sample_token"] for _ in range(5)]
    state = pickle.loads(pickle.dumps(stream.state_dict()))
    resumed = token_samples.stream()
    resumed.load_state_dict(state)
    assert head + _tokens(resumed) == full
    assert resumed.epoch == 1 and resumed.position == 0  # the epoch done: the next one starts afresh


def test_worker_init_fn_selects_the_workers_scenes(token_samples, monkeypatch):
    stream = token_samples.stream(seed=2)
    info = types.SimpleNamespace(id=1, num_workers=2, dataset=stream)
    fake = types.ModuleType("torch.utils.data")
    fake.get_worker_info = lambda: info
    monkeypatch.setitem(sys.modules, "torch", types.ModuleType("torch"))
    monkeypatch.setitem(sys.modules, "torch.utils", types.ModuleType("torch.utils"))
    monkeypatch.setitem(sys.modules, "torch.utils.data", fake)
    worker_init_fn(1)
    assert stream.worker == (1, 2)
    other = token_samples.stream(seed=2)
    other.select_worker(0, 2)
    assert sorted(_tokens(stream) + _tokens(other)) == sorted(token_samples.sample_token.tolist())


def test_a_stream_pickles_small_without_an_open_dataset(token_samples):
    stream = token_samples.shard(0, 2).stream(seed=4)
    data = pickle.dumps(stream)
    assert len(data) < 50_000
    again = pickle.loads(data)
    assert again.samples._ds is None
    assert _tokens(again) == _tokens(stream)
