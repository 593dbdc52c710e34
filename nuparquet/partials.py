"""Hidden partial outputs: every output (a converted dataset, a video, a frames folder) is written as
`.<name>.partial-<pid>` beside its target and renamed into place at the end. A run killed with SIGKILL cannot clean
up, so the next run for the same target removes what dead processes left; a live process's partial (another run
writing the same target right now) is never touched."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

from nuparquet.errors import UsageError


def partial_path(target: Path) -> Path:
    """This process's hidden partial for `target`."""
    return target.parent / f".{target.name}.partial-{os.getpid()}"


def write_text_atomic(target: Path, text: str) -> None:
    """`target` holds `text` whole or keeps what it held: written to this process's partial, then renamed."""
    partial = partial_path(target)
    partial.write_text(text)
    os.replace(partial, target)


def remove_stale(target: Path, kinds: tuple[str, ...] = ("partial", "replaced")) -> list[Path]:
    """Remove `.<target name>.<kind>-<pid>` beside `target` for every pid that is not a running process (and this
    process's own, left by an earlier attempt); returns what was removed."""
    pattern = re.compile(rf"\.{re.escape(target.name)}\.({'|'.join(kinds)})-(\d+)")
    removed = []
    if not target.parent.is_dir():
        return removed
    for path in target.parent.iterdir():
        found = pattern.fullmatch(path.name)
        if found is None or (int(found.group(2)) != os.getpid() and _alive(int(found.group(2)))):
            continue
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def check_apart(out: Path | str, source: Path | str, *, what: str = "the input") -> None:
    """Refuse an output that is, contains or lies inside `source` (`convert D --out D --overwrite` would delete
    the dataroot; `export-json OUT --out OUT` would replace the Parquet)."""
    out_path, source_path = Path(out).absolute().resolve(), Path(source).absolute().resolve()
    if out_path == source_path or source_path in out_path.parents or out_path in source_path.parents:
        relation = ("is" if out_path == source_path else
                    "is inside" if source_path in out_path.parents else "contains")
        raise UsageError(f"{out} {relation} {what} {source}; write the output somewhere else")
