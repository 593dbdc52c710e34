"""Progress reporting: the library reports, the CLI shows.

Long-running library functions (convert, render, synth, ...) take `on_progress: OnProgress | None` and call
it with `Progress` events; they never draw anything. The CLI passes `nuparquet.cli.progress.bars()`, which
draws one tqdm bar per task; a notebook user may pass any callable (or None for silence).

```python
def on_progress(event: Progress) -> None:
    print(event.task, event.done, event.total, event.step)

convert(dataroot, version, out, on_progress=on_progress)
```
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Progress:
    """One progress event of a task.

    task: what is running, e.g. "convert" or "render scene-0061 CAM_FRONT"; one bar per task.
    done: units finished so far; total: units in all (None while unknown; once known it never changes, so a bar's
    percentage only goes up).
    unit: what a unit is ("step", "frame", "scene", "file").
    step: what is being done now, e.g. "read sample_data" ("" when nothing new to say).
    finished: the last event of the task (the bar can close).
    """

    task: str
    done: int
    total: int | None
    unit: str = "step"
    step: str = ""
    finished: bool = False


OnProgress = Callable[[Progress], None]


class Reporter:
    """Counts one task's units and sends events to `on_progress` (a no-op when it is None).

    reporter = Reporter(on_progress, "convert")   # total unknown yet
    reporter.advance(step="read sample")          # done += 1
    reporter.set_total(35)                        # once every unit is counted; never changed after
    reporter.close()                              # the finished event
    """

    def __init__(self, on_progress: OnProgress | None, task: str, total: int | None = None, unit: str = "step"):
        self.on_progress = on_progress
        self.task = task
        self.total = total
        self.unit = unit
        self.done = 0
        self._closed = False
        self._emit("")

    def _emit(self, step: str, finished: bool = False) -> None:
        if self.on_progress is not None:
            self.on_progress(Progress(self.task, self.done, self.total, self.unit, step, finished))

    def advance(self, n: int = 1, step: str = "") -> None:
        self.done += n
        self._emit(step)

    def note(self, step: str) -> None:
        """Say what is being done now without counting a unit."""
        self._emit(step)

    def set_total(self, total: int) -> None:
        """The task's total, once it is known (it was None until then). A bar whose total changed midway would
        read 97% and then 78%: setting it twice is a programming error."""
        if self.total is not None:
            raise RuntimeError(f"{self.task}: the progress total is already {self.total}")
        self.total = max(int(total), self.done)
        self._emit("")

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._emit("", finished=True)

    def __enter__(self) -> Reporter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
