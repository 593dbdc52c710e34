"""A render that is interrupted or killed never leaves a truncated video or a half-filled frames folder at its
output, and never replaces frames it was not asked to replace."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import av
import polars as pl
import pytest

from nuparquet.cli.main import main

KILL_ONCE_WRITING = """
import os, signal, sys
from nuparquet.rendering.video import video
original = video.VideoWriter.write
def write(self, image):
    original(self, image)
    if self.partial.exists() and self.partial.stat().st_size > 0:  # the encoder has started writing: kill it
        os.kill(os.getpid(), signal.SIGKILL)
video.VideoWriter.write = write
from nuparquet.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def frames_of(path: Path) -> int:
    with av.open(str(path)) as container:
        return sum(1 for _ in container.decode(video=0))


def test_a_render_killed_midway_leaves_no_video_and_the_next_run_cleans_up(synth_out, tmp_path):
    out = tmp_path / "scene.mp4"
    args = ["render", str(synth_out), "--scene", "scene-0001", "--out", str(out), "--quiet", "--all-frames"]
    killed = subprocess.run([sys.executable, "-c", KILL_ONCE_WRITING, *args], capture_output=True)
    assert killed.returncode == -9
    assert not out.exists()  # nothing that looks like a finished video
    assert len(list(tmp_path.glob(".scene.mp4.partial-*"))) == 1  # what the killed run was writing
    assert main(args) == 0
    assert frames_of(out) > 6 and list(tmp_path.glob(".scene.mp4.partial-*")) == []


def test_an_interrupted_render_exits_130_and_leaves_nothing(synth_out, tmp_path, monkeypatch):
    from nuparquet.rendering.video import video

    original = video.VideoWriter.write

    def write(self, image):
        original(self, image)
        if self.frames_written == 3:
            raise KeyboardInterrupt

    monkeypatch.setattr(video.VideoWriter, "write", write)
    out, frames = tmp_path / "scene.mp4", tmp_path / "frames"
    code = main(["render", str(synth_out), "--scene", "scene-0001", "--out", str(out), "--frames-dir", str(frames),
                 "--quiet"])
    assert code == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no video, no frames, no partials


def test_frames_dir_holding_frames_is_refused_without_overwrite(synth_out, tmp_path, capsys):
    frames = tmp_path / "frames"
    args = ["render", str(synth_out), "--scene", "scene-0001", "--frames-dir", str(frames), "--quiet"]
    assert main(args) == 0
    assert len(list(frames.glob("*.jpg"))) == 6
    (frames / "notes.txt").write_text("mine")
    (frames / "00000.jpg").write_bytes(b"old")
    assert main(args) == 2 and "--overwrite" in capsys.readouterr().err
    assert (frames / "00000.jpg").read_bytes() == b"old"
    assert main(args + ["--all-frames", "--overwrite"]) == 0
    jpgs = sorted(p.name for p in frames.glob("*.jpg"))
    assert len(jpgs) > 6 and jpgs[0] == "00000.jpg" and (frames / "00000.jpg").read_bytes() != b"old"
    assert (frames / "notes.txt").read_text() == "mine"  # only frames are replaced
    assert [p.name for p in tmp_path.iterdir()] == ["frames"]


def _dataroot_with_one_bad_image(synth_out, tmp_path, make_bad):
    """Symlinks to every CAM_FRONT keyframe image of scene-0001, one replaced by `make_bad(path)`."""
    import os

    import polars as pl

    import nuparquet

    ds = nuparquet.open(synth_out)
    names = (ds.scan("frames").filter((pl.col("scene_name") == "scene-0001") & (pl.col("channel") == "CAM_FRONT")
                                      & pl.col("is_key_frame")).sort("timestamp").collect()["filename"].to_list())
    root = tmp_path / "root"
    for name in names:
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        os.symlink(Path(ds.dataroot) / name, root / name)
    bad = root / names[2]
    original = (Path(ds.dataroot) / names[2]).read_bytes()
    bad.unlink()
    make_bad(bad, original)
    return root, bad, len(names)


def _cut_short(path, original):
    path.write_bytes(original[: len(original) // 2])


def _other_size(path, original):
    import cv2
    import numpy as np

    cv2.imwrite(str(path), np.full((90, 160, 3), 128, np.uint8))


def _named_pipe(path, original):
    import os

    os.mkfifo(path)


@pytest.mark.parametrize("make_bad", [_cut_short, _other_size, _named_pipe])
def test_bad_images_are_reported_and_never_drawn_on(synth_out, tmp_path, capsys, make_bad):
    root, bad, keyframes = _dataroot_with_one_bad_image(synth_out, tmp_path, make_bad)
    out = tmp_path / "x.mp4"
    base = ["render", str(synth_out), "--scene", "scene-0001", "--dataroot", str(root), "--quiet"]
    assert main(base + ["--out", str(out)]) == 0  # a named pipe must not block the render
    err = capsys.readouterr().err
    assert "1 file(s) missing or unreadable" in err and str(bad) in err
    assert frames_of(out) == keyframes  # the bad image's frame repeats the one before: the timing is kept
    index = pl.read_parquet(tmp_path / "x.frames.parquet")
    assert index["drawn"].to_list() == [True, True, False] + [True] * (keyframes - 3)
    assert index["shows_frame"].to_list() == [0, 1, 1] + list(range(3, keyframes))
    assert main(base + ["--out", str(tmp_path / "y.mp4"), "--on-missing", "error"]) == 1
    assert str(bad) in capsys.readouterr().err and not (tmp_path / "y.mp4").exists()


@pytest.mark.parametrize("filename, refused", [("samples/CAM_FRONT/a.jpg", False), ("../../etc/passwd", True),
                                               ("samples/../../x.jpg", True), ("/etc/passwd", True)])
def test_filenames_leaving_the_dataroot_are_refused(tmp_path, filename, refused):
    from nuparquet.rendering.video.pipeline import _image_path

    path = _image_path(tmp_path, filename)
    assert path.endswith("(outside the dataroot: refused)") is refused
    if not refused:
        assert path == str(tmp_path / filename)
