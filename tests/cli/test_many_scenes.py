"""The many-scene verbs from the command line, run in this process (`--engine serial`): a second run with
--resume skips the scenes an earlier run wrote with the same options, says how many, and leaves their files as they
were. (The engines themselves and Ray: tests/engine/, tests/rendering/test_scale_out.py, tests/mcap/.)"""

from __future__ import annotations

import json
import shutil

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


@pytest.mark.parametrize("command, verb, suffix, options", [
    ("render", "rendered", ".mp4", ["--scale", "0.1"]),
    ("export-mcap", "exported", ".mcap", ["--boxes", "keyframes", "--without", "points"]),
])
def test_keep_going_says_how_many_scenes_were_written_when_one_fails(synth_root, synth_out, tmp_path, capsys, command,
                                                                      verb, suffix, options):
    """With --keep-going a failing scene does not stop the others; the run exits 1 and, before naming the failure,
    says how many scenes it did write (the first scene's CAM_FRONT keyframe images are gone, --on-missing error)."""
    def table(name):
        return json.loads((synth_root / SYNTH_VERSION / f"{name}.json").read_text())

    scenes = sorted(s["name"] for s in table("scene"))
    name_of_scene = {s["token"]: s["name"] for s in table("scene")}
    scene_of_sample = {s["token"]: name_of_scene[s["scene_token"]] for s in table("sample")}
    dataroot = tmp_path / "broken"
    for folder in ("samples", "sweeps"):
        if (synth_root / folder).is_dir():
            shutil.copytree(synth_root / folder, dataroot / folder)
    gone = [r["filename"] for r in table("sample_data") if r["is_key_frame"]
            and r["filename"].startswith("samples/CAM_FRONT/") and scene_of_sample[r["sample_token"]] == scenes[0]]
    assert gone and len(scenes) > 1
    for name in gone:
        (dataroot / name).unlink()
    out_dir = tmp_path / "out"
    code = main([command, str(synth_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", "serial", "--quiet",
                 "--dataroot", str(dataroot), "--on-missing", "error", "--keep-going", *options])
    out, err = capsys.readouterr()
    assert code == 1
    assert f"{verb} {len(scenes) - 1} scene(s) -> {out_dir}" in out
    assert scenes[0] in err and "1 unit(s) failed" in err
    assert sorted(p.name for p in out_dir.glob(f"*{suffix}")) == [f"{s}{suffix}" for s in scenes[1:]]
