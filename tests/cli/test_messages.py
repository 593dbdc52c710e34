"""What commands tell the user as they run, in the test's process: the synthetic data's summary line names the
sensor files it wrote, and a render draws its progress bar on stderr unless --quiet."""

from __future__ import annotations

import re

import polars as pl
import pytest
from conftest import SYNTH_VERSION

import nuparquet
from nuparquet.cli.main import main


@pytest.mark.parametrize("flags, files", [([], None), (["--with-lidar"], "lidar/radar"),
                                          (["--with-images", "--with-lidar"], "images and lidar/radar")])
def test_synth_says_which_sensor_files_it_wrote(tmp_path, capsys, flags, files):
    out = tmp_path / "data"
    assert main(["synth", str(out), "--scenes", "1", "--samples-per-scene", "2", "--seed", "3", "--no-can-bus",
                 *flags]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert line.startswith(f"wrote {out / SYNTH_VERSION}: 1 scenes x 2 samples")
    written = {kind for kind, folder in (("lidar/radar", "LIDAR_TOP"), ("images", "CAM_FRONT"))
               if any((out / "samples" / folder).glob("*"))}
    assert (" with " + files if files else " (tables only)") in line
    assert written == ({"images", "lidar/radar"} if files == "images and lidar/radar" else {files} - {None})


def test_a_render_draws_its_progress_bar_on_stderr_unless_quiet(synth_out, tmp_path, capsys):
    scene = "scene-0001"
    args = ["render", str(synth_out), "--scene", scene, "--channel", "CAM_FRONT", "--scale", "0.25"]
    assert main([*args, "--out", str(tmp_path / "a.mp4")]) == 0
    bar = capsys.readouterr().err
    # one keyframe picture per sample of the scene (the JSON's nbr_samples, through the scenes dataset)
    samples = nuparquet.open(synth_out).scan("scenes").filter(pl.col("name") == scene).collect()["nbr_samples"][0]
    assert re.search(rf"render {scene} CAM_FRONT: +0%\|.*\| 0/{samples} ", bar), bar
    assert main([*args, "--out", str(tmp_path / "b.mp4"), "--quiet"]) == 0
    assert f"render {scene}" not in capsys.readouterr().err
