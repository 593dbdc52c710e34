"""The many-scene verbs from the command line, run in this process (`--engine serial`): a second run with
--resume skips the scenes an earlier run wrote with the same options, says how many, and leaves their files as they
were. (The engines themselves and Ray: tests/engine/, tests/rendering/test_scale_out.py, tests/mcap/.)"""

from __future__ import annotations

import json

import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main


@pytest.mark.parametrize("command, verb, suffix, options", [
    ("render", "rendered", ".mp4", ["--scale", "0.1"]),
    ("export-mcap", "exported", ".mcap", ["--boxes", "keyframes", "--without", "images,points"]),
])
def test_resume_skips_the_scenes_an_earlier_run_wrote_and_says_so(synth_root, synth_out, tmp_path, capsys, command,
                                                                  verb, suffix, options):
    scenes = sorted(s["name"] for s in json.loads((synth_root / SYNTH_VERSION / "scene.json").read_text()))
    out_dir = tmp_path / "out"
    run = [command, str(synth_out), "--out-dir", str(out_dir), "--engine", "serial", "--quiet", *options]
    assert main([*run, "--scenes", scenes[0]]) == 0
    first = out_dir / f"{scenes[0]}{suffix}"
    inode = first.stat().st_ino
    capsys.readouterr()
    assert main([*run, "--all-scenes", "--resume"]) == 0
    out = capsys.readouterr().out
    assert f"{verb} {len(scenes) - 1} scene(s) (1 already done, skipped) -> {out_dir}" in out
    assert sorted(p.name for p in out_dir.glob(f"*{suffix}")) == [f"{s}{suffix}" for s in scenes]
    assert first.stat().st_ino == inode  # not written again
