"""The frame loop's decode threads (nuparquet.rendering.video.loop): a render that stops on a missing file returns only
after the reads already running have ended, so no thread of it still reads files (which the caller may be about
to delete) once the error reaches the caller."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from nuparquet.errors import InputError
from nuparquet.rendering.video.loop import render_frames
from nuparquet.rendering.plan import TileLoad, TilePlan

READ_S = 0.4  # a slow read: far longer than it takes to raise and look at the threads


class SlowSource:
    """A tile whose first output's file is missing and whose later outputs take READ_S to read."""

    label = "slow"

    def __init__(self):
        self.finished_reads = 0

    def key(self, t):
        return t

    def load(self, t):
        if t == 0:
            return TileLoad(missing=("samples/CAM_FRONT/missing.jpg",))
        time.sleep(READ_S)
        self.finished_reads += 1
        return TileLoad(data=t)

    def draw(self, t, loaded):
        return np.zeros((4, 4, 3), np.uint8)


class NullSink:
    def write(self, picture):
        pass

    def close(self, index):
        pass

    def abort(self):
        self.aborted = True


def test_a_render_stopped_by_a_missing_file_leaves_no_decode_thread_running():
    source = SlowSource()
    plan = TilePlan(times_us=np.arange(8, dtype=np.float64) * 1e5, layout=((source,),), tile_size=(4, 4))
    sink = NullSink()
    with pytest.raises(InputError, match="missing or unreadable file: samples/CAM_FRONT/missing.jpg"):
        render_frames(plan, lambda pool: sink, on_missing="error", threads=2)
    running = [t for t in threading.enumerate() if t.name.startswith("nuparquet-decode") and t.is_alive()]
    assert running == [] and sink.aborted
    # the reads that had started (one or two: two threads, one took the missing file first) ended before the error
    # came out, and the reads still queued never run
    finished = source.finished_reads
    assert 1 <= finished <= 2
    time.sleep(1.5 * READ_S)
    assert source.finished_reads == finished
