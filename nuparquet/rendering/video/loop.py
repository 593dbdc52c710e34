"""The frame loop, the only Python loop of a render: tiles are read a few outputs ahead on a thread pool
(OpenCV decodes without the GIL) while the main thread draws, composes and hands pictures to the sink (x264
runs its own threads).

Every output is written, so that picture n is at time n / fps: an output with nothing to draw (its images missing)
repeats the picture before it (a placeholder picture when none came before), and the frame index says so
(`frame_index`: each output's tiles, the sample_data each shows, and which picture it repeats)."""

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
from nuparquet.rendering.video.sink import FrameSink

DECODE_AHEAD = 6  # outputs read ahead of the one being drawn


@dataclass
class LoopResult:
    """Pictures written, of which `skipped` had nothing new to show (the picture before repeated), the missing or
    unreadable files (each once), and the frame index rows (`frame_index.SCHEMA`)."""

    written: int = 0
    skipped: int = 0
    missing: list[str] = field(default_factory=list)
    index: list[dict] = field(default_factory=list)


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
    last_picture: tuple[int, np.ndarray] | None = None  # (its frame number, the picture) of the last one drawn

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
            drawn = [tile is not None for tile in tiles]
            nothing = not any(drawn)
            if nothing and last_picture is not None:  # repeat the picture before: the output keeps its time
                result.skipped += 1
                sink.write(last_picture[1])
                shows = last_picture[0]
            else:
                result.skipped += nothing
                tiles = [tile if tile is not None else draw.placeholder(tile_width, tile_height, f"{source.label}: no image")
                         for source, tile in zip(sources, tiles)]
                picture = compose(tiles, plan.row_lengths, tile_width, tile_height)
                sink.write(picture)
                shows = result.written
                last_picture = (shows, picture)
            result.index += _index_rows(result.written, float(plan.times_us[t]), sources, drawn, t, shows)
            result.written += 1
            if reporter is not None:
                reporter.advance()
        if result.written and result.skipped == result.written:  # nothing at all to show: write nothing
            sink.abort()
        else:
            sink.close(result.index)
    except BaseException:
        if sink is not None:
            sink.abort()
        raise
    finally:
        for future in pending:
            future.cancel()
        pool.shutdown(wait=True, cancel_futures=True)
    return result


def _index_rows(frame: int, time_us: float, sources, drawn: list[bool], t: int, shows: int) -> list[dict]:
    """The frame index rows of output `frame` (`frame_index.SCHEMA`): one per tile."""
    rows = []
    for position, (source, was_drawn) in enumerate(zip(sources, drawn)):
        seen = source.shows(t) if hasattr(source, "shows") else None
        rows.append({"frame": frame, "time_us": int(round(time_us)), "tile": position, "channel": source.label,
                     "sample_data_token": seen[0] if seen else None, "timestamp": seen[1] if seen else None,
                     "drawn": bool(was_drawn and seen is not None and shows == frame), "shows_frame": shows})
    return rows
