"""Every scene exported through the engine (`nuparquet export-mcap OUT --all-scenes --out-dir DIR`): one MCAP file
per scene, the same bytes from Ray (a local Ray of 2 CPUs, one session for this module), the process pool, one
process and the one-scene export; a failing scene named, --keep-going, --resume, --where."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import polars as pl
import pytest
import ray

from mcap_files import validate
from nuparquet.cli.main import main
from nuparquet.mcap.options import SUMMARY_NAME

pytestmark = pytest.mark.xdist_group("ray")  # one worker, one Ray session (make test: --dist loadgroup)

SCENES = ["scene-0001", "scene-0002"]
QUIET = ["--quiet", "--boxes", "keyframes"]


@pytest.fixture(scope="module")
def ray_session():
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def one_scene_files(synth_points_out, tmp_path_factory) -> dict[str, bytes]:
    """Each scene exported alone by the one-scene command, in this process."""
    folder = tmp_path_factory.mktemp("one-scene-mcap")
    files = {}
    for scene in SCENES:
        assert main(["export-mcap", str(synth_points_out), "--scene", scene, "--out", str(folder / f"{scene}.mcap"),
                     *QUIET]) == 0
        files[scene] = (folder / f"{scene}.mcap").read_bytes()
    return files


def _files(folder: Path) -> dict[str, bytes]:
    return {p.stem: p.read_bytes() for p in sorted(folder.glob("*.mcap"))}


def _broken_dataroot(root: Path, tmp_path: Path, scene: str, out: Path) -> tuple[Path, str]:
    """A copy of the dataroot without one CAM_BACK image of `scene`; returns it and the file removed."""
    broken = tmp_path / "broken"
    shutil.copytree(root, broken)
    filename = (pl.scan_parquet(f"{out}/frames/**/*.parquet")
                .filter((pl.col("scene_name") == scene) & (pl.col("channel").cast(pl.String) == "CAM_BACK"))
                .sort("timestamp").select("filename").first().collect().item())
    (broken / filename).unlink()
    return broken, filename


def test_files_are_the_same_bytes_on_ray_the_process_pool_and_one_process(ray_session, synth_points_out,
                                                                          one_scene_files, tmp_path, capsys):
    for engine in ("ray", "process", "serial"):
        out_dir = tmp_path / engine
        assert main(["export-mcap", str(synth_points_out), "--all-scenes", "--out-dir", str(out_dir), "--engine",
                     engine, "--workers", "2", *QUIET]) == 0, engine
        assert "exported 2 scene(s)" in capsys.readouterr().out
        assert _files(out_dir) == one_scene_files, engine
        assert sorted(p.name for p in out_dir.iterdir()) == sorted([f"{s}.mcap" for s in SCENES] + [SUMMARY_NAME])
    summary = json.loads((tmp_path / "ray" / SUMMARY_NAME).read_text())
    assert sorted(summary["scenes"]) == SCENES and summary["failed"] == {}
    for scene in SCENES:
        facts = validate(tmp_path / "ray" / f"{scene}.mcap")
        counts = {facts["summary"].channels[c].topic: n
                  for c, n in facts["summary"].statistics.channel_message_counts.items()}
        assert summary["scenes"][scene]["messages"] == counts
        assert summary["scenes"][scene]["bytes"] == len(one_scene_files[scene])


def test_where_selects_the_scenes(synth_points_out, one_scene_files, tmp_path):
    assert main(["export-mcap", str(synth_points_out), "--where", "name > 'scene-0001'", "--out-dir",
                 str(tmp_path / "b"), "--engine", "serial", *QUIET]) == 0
    assert _files(tmp_path / "b") == {"scene-0002": one_scene_files["scene-0002"]}


def test_a_failing_scene_is_named_keep_going_writes_the_others_and_resume_finishes(
        ray_session, synth_root, synth_points_out, one_scene_files, tmp_path, capsys):
    broken, filename = _broken_dataroot(synth_root, tmp_path, "scene-0002", synth_points_out)
    out_dir = tmp_path / "mcap"
    args = ["export-mcap", str(synth_points_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", "ray", *QUIET]
    assert main([*args, "--dataroot", str(broken), "--on-missing", "error"]) == 1
    err = capsys.readouterr().err
    assert "scene-0002: " in err and filename.split("/")[-1] in err and "scene-0001: " not in err
    assert not list(out_dir.glob("*.mcap")) and not (out_dir / SUMMARY_NAME).exists()

    assert main([*args, "--dataroot", str(broken), "--on-missing", "error", "--keep-going"]) == 1
    assert "1 unit(s) failed" in capsys.readouterr().err
    assert _files(out_dir) == {"scene-0001": one_scene_files["scene-0001"]}
    assert list(json.loads((out_dir / SUMMARY_NAME).read_text())["failed"]) == ["scene-0002"]
    inode = (out_dir / "scene-0001.mcap").stat().st_ino

    # the resume digest is the whole options object (--on-missing included); where the files are is not a setting
    assert main([*args, "--on-missing", "error", "--resume"]) == 0
    assert "exported 1 scene(s) (1 already done, skipped)" in capsys.readouterr().out
    assert _files(out_dir) == one_scene_files
    assert (out_dir / "scene-0001.mcap").stat().st_ino == inode  # not rewritten
    assert not (out_dir / ".nuparquet-parts").exists()


def test_missing_files_are_counted_in_the_summary_and_warned(synth_root, synth_points_out, tmp_path, capsys):
    broken, filename = _broken_dataroot(synth_root, tmp_path, "scene-0001", synth_points_out)
    out_dir = tmp_path / "mcap"
    assert main(["export-mcap", str(synth_points_out), "--scenes", "scene-0001", "--out-dir", str(out_dir),
                 "--engine", "serial", "--dataroot", str(broken), *QUIET]) == 0
    assert "1 sensor file(s) missing" in capsys.readouterr().err
    entry = json.loads((out_dir / SUMMARY_NAME).read_text())["scenes"]["scene-0001"]
    assert entry["missing"] == 1 and entry["first_missing"] == [str(broken / filename)]
    # the scene's file is DIR/<scene>.mcap, named so in the summary; nothing else is left in the folder
    assert sorted(p.name for p in out_dir.iterdir()) == sorted(["scene-0001.mcap", SUMMARY_NAME])
    assert entry["file"] == "scene-0001.mcap"
