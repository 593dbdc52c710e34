"""Hidden partial outputs left by killed runs are removed by the next run for the same target; a live process's
partial is never touched (two runs may write side by side)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from conftest import SYNTH_VERSION
from nuparquet.atomic import check_apart, check_target, remove_stale
from nuparquet.cli.main import main
from nuparquet.errors import UsageError


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid  # reaped: no process has this pid now (pids are not reused this quickly)


def test_remove_stale_removes_dead_runs_partials_and_keeps_live_ones(tmp_path):
    target = tmp_path / "out"
    dead, live = _dead_pid(), os.getppid()  # our parent (pytest's launcher or shell) is alive
    (tmp_path / f".out.partial-{dead}").mkdir()
    (tmp_path / f".out.partial-{dead}" / "file").write_text("x")
    (tmp_path / f".out.replaced-{dead}").mkdir()
    (tmp_path / f".out.partial-{live}").mkdir()
    (tmp_path / f".other.partial-{dead}").mkdir()  # another target's: not ours to judge
    (tmp_path / f".out.partial-{dead}x").mkdir()  # not a partial's name
    removed = remove_stale(target)
    assert sorted(p.name for p in removed) == sorted([f".out.partial-{dead}", f".out.replaced-{dead}"])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [f".out.partial-{live}", f".other.partial-{dead}", f".out.partial-{dead}x"])


def test_convert_removes_a_killed_runs_partial_folder(synth_root, tmp_path):
    dead = _dead_pid()
    stale = tmp_path / f".out.partial-{dead}"
    (stale / "tables").mkdir(parents=True)
    assert main(["convert", str(synth_root), "--version", SYNTH_VERSION, "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_leftover_partial_with_this_process_pid_is_removed_as_stale(tmp_path):
    """pids are reused (containers start every run as pid 1..n): a partial named with our own pid cannot be a live
    run's (we are not writing it now), so it is an earlier attempt's and goes; the live parent's stays."""
    target = tmp_path / "out"
    own, live = tmp_path / f".out.partial-{os.getpid()}", tmp_path / f".out.partial-{os.getppid()}"
    own.mkdir()
    (own / "half.parquet").write_text("x")
    live.mkdir()
    assert remove_stale(target) == [own]
    assert sorted(p.name for p in tmp_path.iterdir()) == [live.name]


def test_atomic_file_replaces_the_target_whole_or_leaves_it_as_it_was(tmp_path):
    from nuparquet.atomic import atomic_file, partial_path

    target = tmp_path / "infos.pkl"
    target.write_text("old")
    stale = tmp_path / f".infos.pkl.partial-{_dead_pid()}"  # a killed index run's leftover
    stale.write_text("half")
    try:
        with atomic_file(target) as partial:
            partial.write_text("new, but")
            raise RuntimeError("killed mid-write")
    except RuntimeError:
        pass
    assert target.read_text() == "old" and not partial_path(target).exists() and not stale.exists()
    with atomic_file(target) as partial:
        partial.write_text("new")
    assert target.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["infos.pkl"]


def test_check_target_refuses_an_existing_output_unless_told_to_replace_it(tmp_path):
    out = tmp_path / "out"
    assert check_target(out, overwrite=False) == out  # not there yet: fine either way
    out.mkdir()
    with pytest.raises(UsageError, match=r"out already exists; pass --overwrite to replace it"):
        check_target(out, overwrite=False)
    assert check_target(out, overwrite=True) == out
    (tmp_path / "file").write_text("x")
    with pytest.raises(UsageError, match="exists and is not a directory"):
        check_target(tmp_path / "file", overwrite=True)


def test_check_apart_refuses_an_output_that_is_inside_or_contains_the_input_and_names_how(tmp_path):
    source = tmp_path / "data"
    for out, relation in ((source, "is"), (source / "videos", "is inside"), (tmp_path, "contains"),
                          (tmp_path / "data" / ".." / "data", "is")):  # the same folder spelt another way
        with pytest.raises(UsageError) as refused:
            check_apart(out, source, what="the dataroot")
        assert str(refused.value) == f"{out} {relation} the dataroot {source}; write the output somewhere else"
    check_apart(tmp_path / "data-videos", source)  # a sibling whose name starts with the input's: apart
    check_apart(tmp_path / "other" / "data", source)
