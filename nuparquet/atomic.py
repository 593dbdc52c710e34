"""Atomic outputs, one convention for every writer: an output (a converted dataset, a JSON export, a video, a
frames folder, an info file, an index folder, an evaluation, a picture, an MCAP file) is written as
`.<name>.partial-<pid>` beside its target and renamed into place only when complete, so a failed or interrupted
run never leaves a complete-looking output and never touches an existing one unless asked to replace it
(`atomic_directory`, `atomic_file`, `write_text_atomic`, and `move_into_place` for writers that hold their partial
open themselves: the video and MCAP writers, the frames folder, the engine's commit). This module is the only one
that renames outputs (`tests/test_architecture.py` checks it).

A run killed with SIGKILL cannot clean up, so the next run for the same target removes what dead processes left
(`remove_stale`); a live process's partial (another run writing the same target right now) is never touched.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

from nuparquet.errors import EnvironmentFault, UsageError


def partial_path(target: Path) -> Path:
    """This process's hidden partial for `target`."""
    return target.parent / f".{target.name}.partial-{os.getpid()}"


def move_into_place(source: Path, target: Path) -> None:
    """Rename `source` (a finished partial, or a committed part file) to `target`, replacing a file there: one
    rename on one file system, so `target` is either the old file or the new one, never a half."""
    try:
        os.replace(source, target)
    except OSError as exc:
        raise EnvironmentFault(f"{target}: {exc.strerror or exc}") from exc


def write_text_atomic(target: Path, text: str) -> None:
    """`target` holds `text` whole or keeps what it held: written to this process's partial, then renamed."""
    with atomic_file(target) as partial:
        partial.write_text(text)


@contextlib.contextmanager
def atomic_file(target: Path) -> Iterator[Path]:
    """Yield this process's partial for the file `target` (what dead runs left is removed first); on success it
    replaces `target` by a rename, on failure it is removed and `target` keeps what it held."""
    target = Path(target)
    remove_stale(target)
    partial = partial_path(target)
    try:
        yield partial
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)


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


def check_target(out: Path | str, *, overwrite: bool) -> Path:
    """Refuse an existing output unless told to replace it (call before doing the work, to fail fast)."""
    out = Path(out).absolute()
    if out.is_symlink() and not out.exists():
        raise EnvironmentFault(f"{out} is a symbolic link to {os.readlink(out)}, which does not exist; remove the link "
                               "or choose another output path")
    blocking = next((p for p in out.parents if p.exists() and not p.is_dir()), None)
    if blocking is not None:
        raise EnvironmentFault(f"cannot create {out}: {blocking} is a file, not a folder")
    if out.exists() and not overwrite:
        raise UsageError(f"{out} already exists; pass --overwrite to replace it")
    if out.exists() and not out.is_dir():
        raise UsageError(f"{out} exists and is not a directory")
    return out


@contextlib.contextmanager
def atomic_directory(out: Path, *, overwrite: bool, checked: bool = False) -> Iterator[Path]:
    """Yield a temporary sibling of `out` to write into; on success it replaces `out` by renames. `checked`: the
    caller refused an unwanted existing `out` itself (an empty folder may be written into, as `eval --out`)."""
    out = Path(out).absolute() if checked else check_target(out, overwrite=overwrite)
    overwrite = overwrite or checked
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale(out)  # what killed runs left (SIGKILL cannot clean up); a live run's partial stays
    tmp = partial_path(out)
    tmp.mkdir()
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if out.exists() or out.is_symlink():
        if not overwrite:  # it appeared while we worked (another run, another user): never replace it
            shutil.rmtree(tmp, ignore_errors=True)
            raise UsageError(f"{out} appeared while the output was being written; nothing was replaced (pass "
                             "--overwrite to replace it)")
        old = out.parent / f".{out.name}.replaced-{os.getpid()}"
        os.rename(out, old)
    os.rename(tmp, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
