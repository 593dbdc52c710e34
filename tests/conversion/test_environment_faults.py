"""Faults of the machine, not the data: each ends as one line naming the path and the reason, exit 1, with nothing
left that looks like an output and no hidden partial folder."""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main

V = SYNTH_VERSION


def _run(synth_root, out, capsys) -> tuple[int, str]:
    code = main(["convert", str(synth_root), "--version", V, "--out", str(out), "--quiet"])
    return code, capsys.readouterr().err


def test_output_parent_is_a_file(synth_root, tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    code, err = _run(synth_root, tmp_path / "afile" / "out", capsys)
    assert code == 1 and err.count("\n") == 1 and "afile is a file, not a folder" in err and "Traceback" not in err
    assert (tmp_path / "afile").read_text() == "x"


def test_output_is_a_dangling_symlink(synth_root, tmp_path, capsys):
    os.symlink(tmp_path / "nowhere", tmp_path / "link")
    code, err = _run(synth_root, tmp_path / "link", capsys)
    assert code == 1 and "symbolic link" in err and "does not exist" in err
    assert os.path.islink(tmp_path / "link") and not (tmp_path / "nowhere").exists()


def test_a_full_disk_midway_leaves_nothing(synth_root, tmp_path, capsys, monkeypatch):
    from nuparquet.conversion import write

    original = write.DatasetWriter.write
    calls = {"n": 0}

    def failing(self, table):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError(errno.ENOSPC, "No space left on device", str(self.path))
        original(self, table)

    monkeypatch.setattr(write.DatasetWriter, "write", failing)
    code, err = _run(synth_root, tmp_path / "out", capsys)
    assert code == 1 and "No space left on device" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no OUT, no .out.partial-*


@contextlib.contextmanager
def _read_only(folder: Path):
    """`folder` read-only for this process: chmod for a normal user; as root (CI), which chmod does not stop, the
    ext4 immutable attribute."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        try:
            yield
        finally:
            folder.chmod(0o755)
        return
    if shutil.which("chattr") is None or subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode:
        pytest.skip("running as root on a filesystem without chattr +i: no way to make a folder read-only")
    try:
        yield
    finally:
        subprocess.run(["chattr", "-i", str(folder)], check=True)


def test_a_read_only_output_folder_is_one_line_and_leaves_nothing(synth_root, tmp_path, capsys):
    parent = tmp_path / "readonly"
    parent.mkdir()
    with _read_only(parent):
        with pytest.raises(OSError):  # the folder really is read-only for us
            (parent / "probe").write_text("x")
        code, err = _run(synth_root, parent / "out", capsys)
        left = sorted(p.name for p in parent.iterdir())
    assert code == 1 and err.count("\n") == 1 and "Traceback" not in err
    assert f"cannot write {parent / 'out'} in {parent}: " in err and ("ermission denied" in err or "not permitted" in err)
    assert left == []
