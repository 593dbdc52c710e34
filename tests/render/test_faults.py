"""A render that is interrupted or killed never leaves a truncated video or a half-filled frames folder at its
output, and never replaces frames it was not asked to replace."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import av

from nuparquet.cli.main import main

KILL_ONCE_WRITING = """
import os, signal, sys
from nuparquet.render import video
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
    from nuparquet.render import video

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
