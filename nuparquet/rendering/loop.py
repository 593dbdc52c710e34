"""The frame loop, the only Python loop of a render: tiles are read a few outputs ahead on a thread pool
(OpenCV decodes without the GIL) while the main thread draws, composes and hands pictures to the sink (x264
runs its own threads)."""

from __future__ import annotations

from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from nuparquet.errors import InputError
from nuparquet.progress import Reporter
from nuparquet.rendering import draw
from nuparquet.rendering.mosaic import compose
from nuparquet.rendering.plan import TileLoad, TilePlan
from nuparquet.rendering.sink import FrameSink

DECODE_AHEAD = 6  # outputs read ahead of the one being drawn


@dataclass
class LoopResult:
    """Pictures written and skipped (nothing to show), and the missing or unreadable files, each once."""

    written: int = 0
    skipped: int = 0
    missing: list[str] = field(default_factory=list)


def render_frames(plan: TilePlan, make_sink, *, on_missing: str = "skip", threads: int = 2,
                  reporter: Reporter | None = None) -> LoopResult:
    """Draw every output of `plan` into the sink `make_sink(executor)` returns.

    An output is skipped when no tile has anything to show; a tile with nothing shows a placeholder. With
    `on_missing="error"` the first missing or unreadable file raises InputError (naming it) and the sink is
    aborted.
    """
    sources = plan.sources
    tile_width, tile_height = plan.tile_size
    result = LoopResult()
    seen_missing: set[str] = set()
    last_drawn: dict[int, tuple[object, np.ndarray]] = {}  # tile -> (key, drawn tile): reuse a repeated frame

    def load_output(t: int) -> list[TileLoad]:
        return [source.load(t) for source in sources]

    pool = ThreadPoolExecutor(max_workers=max(1, threads), thread_name_prefix="nuparquet-decode")
    sink: FrameSink | None = None
    pending: deque[Future] = deque()
    next_to_submit = 0
    try:
        while next_to_submit < len(plan) and len(pending) < DECODE_AHEAD:  # decoding starts while the encoder opens
            pending.append(pool.submit(load_output, next_to_submit))
            next_to_submit += 1
        sink = make_sink(pool)
        for t in range(len(plan)):
            while next_to_submit < len(plan) and len(pending) < DECODE_AHEAD:
                pending.append(pool.submit(load_output, next_to_submit))
                next_to_submit += 1
            loads = pending.popleft().result()
            for path in (path for load in loads for path in load.missing):
                if on_missing == "error":
                    raise InputError(f"missing or unreadable file: {path} (--on-missing skip renders without it; "
                                     "--dataroot says where the images are)")
                if path not in seen_missing:
                    seen_missing.add(path)
                    result.missing.append(path)

            tiles: list[np.ndarray | None] = []
            for index, (source, load) in enumerate(zip(sources, loads)):
                key = source.key(t)
                if key is not None and index in last_drawn and last_drawn[index][0] == key:
                    tiles.append(last_drawn[index][1])
                    continue
                tile = source.draw(t, load)
                if tile is not None:
                    last_drawn[index] = (key, tile)
                tiles.append(tile)
            if all(tile is None for tile in tiles):
                result.skipped += 1
            else:
                tiles = [tile if tile is not None else draw.placeholder(tile_width, tile_height, f"{source.label}: no image")
                         for source, tile in zip(sources, tiles)]
                sink.write(compose(tiles, plan.row_lengths, tile_width, tile_height))
                result.written += 1
            if reporter is not None:
                reporter.advance()
        sink.close()
    except BaseException:
        if sink is not None:
            sink.abort()
        raise
    finally:
        for future in pending:
            future.cancel()
        pool.shutdown(wait=True, cancel_futures=True)
    return result
