"""Bad option values and damaged outputs end as one clear message with the right exit code, never a traceback,
and never write into the converted dataset."""

from __future__ import annotations

import shutil

import pytest

from nuparquet.cli.main import main


@pytest.mark.parametrize("args, message", [
    (["stats", "{out}", "--bin-width", "0"], "--bin-width must be a positive number"),
    (["stats", "{out}", "--bin-width", "-5"], "--bin-width must be a positive number"),
    (["stats", "{out}", "--bin-width", "nan"], "--bin-width must be a positive number"),
    (["stats", "{out}", "--max-rows", "0"], "--max-rows must be at least 1"),
    (["render", "{out}", "--scene", "scene-0001", "--out", "{tmp}"], "is a directory"),
    (["render", "{out}", "--scene", "scene-0001", "--out", "{out}/manifest.json"], "inside the converted dataset"),
    (["render", "{out}", "--scene", "scene-0001", "--frames-dir", "{out}/rendered"], "inside the converted dataset"),
    (["render", "{out}", "--scene", "scene-0001", "--channel", "RADAR_FRONT", "--out", "{tmp}/r.mp4"],
     "RADAR_FRONT is a radar channel; render draws camera channels: CAM_BACK,"),
    (["render", "{out}", "--scene", "scene-0001", "--channel", "LIDAR_TOP", "--out", "{tmp}/r.mp4"],
     "LIDAR_TOP is a lidar channel"),
    (["render", "{out}", "--scene", "scene-0001", "--channel", "CAM_NOWHERE", "--out", "{tmp}/r.mp4"],
     "unknown channel 'CAM_NOWHERE' for scene-0001"),
    (["convert", "{root}", "--version", "v1.0-synth", "--out", "{tmp}/x", "--sensors", "lidar", "--ray-address", "auto"],
     "--ray-address needs --engine ray"),
    (["validate", "{root}", "--version", ""], "--version must name the version folder"),
    (["validate", "{root}", "--version", ".."], "--version must name the version folder"),
    (["convert", "{root}", "--version", " ", "--out", "{tmp}/x"], "--version must name the version folder"),
])
def test_usage_errors_exit_2_with_the_reason(synth_root, synth_out, tmp_path, capsys, args, message):
    copy = tmp_path / "out"
    shutil.copytree(synth_out, copy)
    before = (copy / "manifest.json").read_bytes()
    filled = [a.format(out=copy, tmp=tmp_path, root=synth_root) for a in args]
    assert main(filled) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert (copy / "manifest.json").read_bytes() == before and not (copy / "rendered").exists()


@pytest.mark.parametrize("damage, message", [
    (b"\xae\xff\x00", "cannot be read as text"),
    (b"{not json", "is not valid JSON"),
    (b'{"format": "nuparquet", "format_version": "1", "datasets": {"frames": {}}}', "no integer format_version"),
    (b'{"format": "nuparquet", "format_version": 2, "datasets": {}}', "lists no datasets"),
])
@pytest.mark.parametrize("command", [["info"], ["stats"], ["sql", "SELECT 1"], ["export-json"]])
def test_a_damaged_manifest_is_a_clear_error_naming_it(synth_out, tmp_path, capsys, damage, message, command):
    copy = tmp_path / "out"
    shutil.copytree(synth_out, copy)
    (copy / "manifest.json").write_bytes(damage)
    args = [command[0], str(copy), *command[1:]]
    if command[0] == "export-json":
        args += ["--out", str(tmp_path / "json")]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "manifest.json" in err and message in err and "Traceback" not in err


@pytest.mark.parametrize("command", [["info"], ["stats"], ["sql", "SELECT count(*) AS n FROM annotations"],
                                     ["render", "--scene", "scene-0001", "--out", "{tmp}/x.mp4", "--quiet"]])
def test_a_truncated_parquet_file_is_named(synth_out, tmp_path, capsys, command):
    copy = tmp_path / "out"
    shutil.copytree(synth_out, copy)
    damaged = sorted((copy / "annotations").glob("*.parquet"))[0]
    damaged.write_bytes(damaged.read_bytes()[:1000])
    args = [command[0], str(copy), *(a.format(tmp=tmp_path) for a in command[1:])]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert f"{damaged} is damaged" in err and "convert the dataset again" in err and "Traceback" not in err
    assert not (tmp_path / "x.mp4").exists()


@pytest.mark.parametrize("args, message", [
    (["validate", "{root}"], "the following arguments are required: --version"),
    # report renders every scene in one job: --keep-going and --resume are not its flags (an unknown OUT: the
    # run would fail at once if they were taken)
    (["report", "{tmp}/missing", "--out", "{tmp}/report", "--keep-going"], "unrecognized arguments: --keep-going"),
    (["report", "{tmp}/missing", "--out", "{tmp}/report", "--resume"], "unrecognized arguments: --resume"),
])
def test_a_missing_required_flag_or_a_flag_the_command_lacks_is_a_usage_error(synth_root, tmp_path, capsys, args,
                                                                             message):
    with pytest.raises(SystemExit) as exit_:
        main([a.format(tmp=tmp_path, root=synth_root) for a in args])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: nuparquet ") and message in err and "Traceback" not in err
    assert not (tmp_path / "report").exists()
