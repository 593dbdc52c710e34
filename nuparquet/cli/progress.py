"""Progress bars on stderr for the library's `Progress` events (see `nuparquet.progress`)."""

from __future__ import annotations

import sys

from nuparquet.progress import OnProgress, Progress


def bars(enabled: bool = True, *, leave: bool = False) -> OnProgress | None:
    """An `on_progress` callback drawing one tqdm bar per task on stderr, or None when not `enabled`."""
    if not enabled:
        return None
    from tqdm import tqdm

    open_bars: dict[str, tqdm] = {}

    def on_progress(event: Progress) -> None:
        bar = open_bars.get(event.task)
        if bar is None:
            if event.finished:
                return
            bar = open_bars[event.task] = tqdm(total=event.total, desc=event.task, unit=event.unit, file=sys.stderr,
                                               dynamic_ncols=True, leave=leave)
        if event.total != bar.total:
            bar.total = event.total
            bar.refresh()
        if event.done != bar.n:
            bar.update(event.done - bar.n)
        if event.step:
            bar.set_postfix_str(event.step)
        if event.finished:
            bar.close()
            del open_bars[event.task]

    return on_progress
