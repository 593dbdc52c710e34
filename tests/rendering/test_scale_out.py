"""Every scene rendered through the engine (`nuparquet render OUT --all-scenes --out-dir DIR`): one video per
scene, the same bytes from Ray (a local Ray of 2 CPUs, one session for this module), the process pool, one
process and the one-scene render; a failing scene named, --keep-going, --resume.

The dataset: 3 synthetic scenes x 3 samples with images, rendered at scale 0.1 (a few kB per video).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import av
import pytest
import ray

from nuparquet.cli.main import main
from nuparquet.rendering.video.options import SUMMARY_NAME

pytestmark = pytest.mark.xdist_group("ray")  # one worker, one Ray session (make test: --dist loadgroup)

VERSION = "v1.0-synth"
SCENES = ["scene-0001", "scene-0002", "scene-0003"]
SMALL = ["--scale", "0.1", "--quiet"]


@pytest.fixture(scope="module")
def ray_session():
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def scenes_root(tmp_path_factory) -> Path:
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("scale-out") / "data"
    synthesize(root, scenes=3, samples_per_scene=3, with_images=True, with_lidar=False, seed=5, version=VERSION)
    return root


@pytest.fixture(scope="module")
def scenes_out(scenes_root) -> Path:
    from nuparquet.conversion import convert

    out = scenes_root.parent / "out"
    convert(scenes_root, VERSION, out)
    return out


@pytest.fixture(scope="module")
def keyframe_images(scenes_root) -> dict[str, list[str]]:
    """scene name -> its CAM_FRONT keyframe image files, from the JSON tables (not from the Parquet)."""
    def table(name):
        return json.loads((scenes_root / VERSION / f"{name}.json").read_text())

    scene_of_sample = {s["token"]: s["scene_token"] for s in table("sample")}
    name_of_scene = {s["token"]: s["name"] for s in table("scene")}
    channel_of_sensor = {s["token"]: s["channel"] for s in table("sensor")}
    channel_of_calibration = {c["token"]: channel_of_sensor[c["sensor_token"]] for c in table("calibrated_sensor")}
    images: dict[str, list[str]] = {}
    for record in table("sample_data"):
        if record["is_key_frame"] and channel_of_calibration[record["calibrated_sensor_token"]] == "CAM_FRONT":
            images.setdefault(name_of_scene[scene_of_sample[record["sample_token"]]], []).append(record["filename"])
    return images


@pytest.fixture(scope="module")
def one_process_videos(scenes_out, tmp_path_factory) -> dict[str, bytes]:
    """Each scene rendered alone by the one-scene command (`--scene S --out S.mp4`), in this process."""
    folder = tmp_path_factory.mktemp("one-scene")
    videos = {}
    for scene in SCENES:
        assert main(["render", str(scenes_out), "--scene", scene, "--out", str(folder / f"{scene}.mp4"), *SMALL]) == 0
        videos[scene] = (folder / f"{scene}.mp4").read_bytes()
    return videos


def _broken_dataroot(scenes_root: Path, tmp_path: Path, images: list[str]) -> Path:
    """A dataroot holding the CAM_FRONT images except `images` (one scene's)."""
    root = tmp_path / "broken-root"
    shutil.copytree(scenes_root / "samples" / "CAM_FRONT", root / "samples" / "CAM_FRONT")
    for name in images:
        (root / name).unlink()
    return root


def _videos(folder: Path) -> dict[str, bytes]:
    return {p.stem: p.read_bytes() for p in sorted(folder.glob("*.mp4"))}


def test_ray_renders_every_scene_to_one_video_of_its_keyframes(ray_session, scenes_out, keyframe_images, tmp_path,
                                                               capsys):
    out_dir = tmp_path / "videos"
    assert main(["render", str(scenes_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", "ray", *SMALL]) == 0
    assert "rendered 3 scene(s)" in capsys.readouterr().out
    assert sorted(p.name for p in out_dir.iterdir()) == sorted([f"{s}.mp4" for s in SCENES] + [SUMMARY_NAME]
                                                               + [f"{s}.frames.parquet" for s in SCENES])
    summary = json.loads((out_dir / SUMMARY_NAME).read_text())
    assert sorted(summary["scenes"]) == SCENES and summary["failed"] == {}
    for scene in SCENES:
        with av.open(str(out_dir / f"{scene}.mp4")) as video:
            frames = sum(1 for _ in video.decode(video=0))
        assert frames == len(keyframe_images[scene]) == summary["scenes"][scene]["frames_written"] == 3


def test_videos_are_the_same_bytes_on_ray_the_process_pool_and_one_process(ray_session, scenes_out,
                                                                           one_process_videos, tmp_path):
    for engine in ("ray", "process", "serial"):
        out_dir = tmp_path / engine
        assert main(["render", str(scenes_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", engine,
                     "--workers", "2", *SMALL]) == 0
        assert _videos(out_dir) == one_process_videos, engine


def test_scenes_and_where_select_the_scenes_rendered(scenes_out, tmp_path):
    assert main(["render", str(scenes_out), "--scenes", "scene-0003,scene-0001", "--out-dir", str(tmp_path / "a"),
                 "--engine", "serial", *SMALL]) == 0
    assert sorted(_videos(tmp_path / "a")) == ["scene-0001", "scene-0003"]
    assert main(["render", str(scenes_out), "--where", "name > 'scene-0001'", "--out-dir", str(tmp_path / "b"),
                 "--engine", "serial", *SMALL]) == 0
    assert sorted(_videos(tmp_path / "b")) == ["scene-0002", "scene-0003"]


def test_unknown_scene_or_bad_where_is_refused_before_any_work(scenes_out, tmp_path, capsys):
    assert main(["render", str(scenes_out), "--scenes", "scene-9999", "--out-dir", str(tmp_path / "x"), *SMALL]) == 2
    assert "unknown scene 'scene-9999'; valid scenes: scene-0001, scene-0002, scene-0003" in capsys.readouterr().err
    assert main(["render", str(scenes_out), "--where", "no_such_column = 1", "--out-dir", str(tmp_path / "x"),
                 *SMALL]) == 1
    assert "no_such_column" in capsys.readouterr().err
    assert not list((tmp_path / "x").glob("*.mp4")) if (tmp_path / "x").exists() else True


def test_a_failing_scene_is_named_and_nothing_is_committed(ray_session, scenes_root, scenes_out, keyframe_images,
                                                           tmp_path, capsys):
    broken = _broken_dataroot(scenes_root, tmp_path, keyframe_images["scene-0002"])
    out_dir = tmp_path / "videos"
    code = main(["render", str(scenes_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", "ray",
                 "--dataroot", str(broken), "--on-missing", "error", *SMALL])
    err = capsys.readouterr().err
    assert code == 1
    assert "scene-0002: " in err and keyframe_images["scene-0002"][0].split("/")[-1] in err
    assert "scene-0001: " not in err and "scene-0003: " not in err
    assert not list(out_dir.glob("*.mp4")) and not (out_dir / SUMMARY_NAME).exists()


def test_keep_going_writes_the_other_scenes_and_resume_renders_only_the_failed_one(
        ray_session, scenes_root, scenes_out, keyframe_images, one_process_videos, tmp_path, capsys):
    broken = _broken_dataroot(scenes_root, tmp_path, keyframe_images["scene-0002"])
    out_dir = tmp_path / "videos"
    code = main(["render", str(scenes_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", "ray",
                 "--dataroot", str(broken), "--keep-going", *SMALL])
    assert code == 1
    assert "1 unit(s) failed" in capsys.readouterr().err
    assert _videos(out_dir) == {s: one_process_videos[s] for s in ("scene-0001", "scene-0003")}
    assert list(json.loads((out_dir / SUMMARY_NAME).read_text())["failed"]) == ["scene-0002"]
    inodes = {p.name: p.stat().st_ino for p in out_dir.glob("*.mp4")}

    assert main(["render", str(scenes_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", "ray",
                 "--resume", *SMALL]) == 0
    assert "rendered 1 scene(s) (2 already done, skipped)" in capsys.readouterr().out
    assert _videos(out_dir) == one_process_videos
    assert {p.name: p.stat().st_ino for p in out_dir.glob("*.mp4") if p.name in inodes} == inodes  # not rewritten
    summary = json.loads((out_dir / SUMMARY_NAME).read_text())
    assert sorted(summary["scenes"]) == SCENES and summary["failed"] == {}
    assert not (out_dir / ".nuparquet-parts").exists()


def test_resume_after_a_stopped_run_reuses_the_scenes_it_finished(scenes_root, scenes_out, keyframe_images,
                                                                  one_process_videos, tmp_path, capsys):
    broken = _broken_dataroot(scenes_root, tmp_path, keyframe_images["scene-0002"])
    out_dir = tmp_path / "videos"
    # One process, scenes in name order: scene-0001 finishes, scene-0002 fails, scene-0003 never starts.
    assert main(["render", str(scenes_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", "serial",
                 "--dataroot", str(broken), *SMALL]) == 1
    assert not list(out_dir.glob("*.mp4"))
    capsys.readouterr()
    assert main(["render", str(scenes_out), "--all-scenes", "--out-dir", str(out_dir), "--engine", "serial",
                 "--resume", *SMALL]) == 0
    assert "rendered 2 scene(s) (1 already done, skipped)" in capsys.readouterr().out
    assert _videos(out_dir) == one_process_videos


def test_resume_renders_again_scenes_made_with_other_options(scenes_out, tmp_path, capsys):
    out_dir = tmp_path / "videos"
    assert main(["render", str(scenes_out), "--scenes", "scene-0001,scene-0002", "--out-dir", str(out_dir),
                 "--engine", "serial", *SMALL]) == 0
    small = _videos(out_dir)
    capsys.readouterr()
    assert main(["render", str(scenes_out), "--scenes", "scene-0001,scene-0002", "--out-dir", str(out_dir),
                 "--engine", "serial", "--resume", "--quiet", "--scale", "0.15"]) == 0
    assert "rendered 2 scene(s) ->" in capsys.readouterr().out  # none skipped: the scale changed
    bigger = _videos(out_dir)
    assert all(bigger[scene] != small[scene] for scene in small)
    with av.open(str(out_dir / "scene-0001.mp4")) as video:
        assert (video.streams.video[0].codec_context.width, video.streams.video[0].codec_context.height) == (240, 136)


@pytest.fixture(scope="module")
def points_root(tmp_path_factory) -> Path:
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("scale-out-points") / "data"
    synthesize(root, scenes=3, samples_per_scene=2, with_lidar=True, seed=6, version=VERSION, with_can_bus=False)
    return root


def test_points_convert_to_the_same_bytes_on_ray_the_process_pool_and_one_process(ray_session, points_root, tmp_path):
    """`convert --sensors lidar,radar` runs each scene as an engine task: one part per scene, committed in scene
    order, the same files whichever engine ran them; the lidar points equal the .pcd.bin files read with numpy."""
    import numpy as np
    import pyarrow.parquet as pq

    parts = {}
    for engine, jobs in (("ray", "2"), ("process", "2"), ("serial", "1")):
        out = tmp_path / engine
        assert main(["convert", str(points_root), "--version", VERSION, "--out", str(out), "--sensors", "lidar,radar",
                     "--engine", engine, "--jobs", jobs, "--quiet"]) == 0
        parts[engine] = {p.relative_to(out).as_posix(): p.read_bytes()
                         for name in ("lidar_points", "radar_points") for p in sorted((out / name).iterdir())}
        assert not list(out.glob(".*parts*"))  # the engine's part folders are gone
    assert sorted(parts["ray"]) == [f"{name}/part-{i:05d}.parquet" for name in ("lidar_points", "radar_points")
                                    for i in range(len(SCENES))]
    assert parts["ray"] == parts["process"] == parts["serial"]
    table = pq.read_table(tmp_path / "ray" / "lidar_points").to_pandas()
    sample_data = json.loads((points_root / VERSION / "sample_data.json").read_text())
    lidar_keyframes = [r for r in sample_data if r["is_key_frame"] and "LIDAR_TOP" in r["filename"]]
    assert len(lidar_keyframes) == len(SCENES) * 2
    for record in lidar_keyframes:
        expected = np.fromfile(points_root / record["filename"], dtype=np.float32).reshape(-1, 5)
        ours = table[table["sample_data_token"] == record["token"]].sort_values("point_index")
        assert np.array_equal(ours[["x", "y", "z", "intensity"]].to_numpy(np.float32), expected[:, :4])


def test_a_second_run_keeps_the_summary_entries_of_scenes_it_did_not_render_and_ignores_a_broken_summary(
        scenes_out, tmp_path, capsys):
    """The summary lists every video in the folder: rendering one more scene keeps the entries of the scenes an
    earlier run rendered there (their files are present); a summary that is not a summary (a JSON list, `scenes`
    not an object) is read as none, not a crash."""
    from nuparquet.rendering.video.options import SUMMARY_NAME

    out_dir = tmp_path / "videos"
    assert main(["render", str(scenes_out), "--scenes", "scene-0001", "--out-dir", str(out_dir), "--engine", "serial",
                 *SMALL]) == 0
    assert main(["render", str(scenes_out), "--scenes", "scene-0002", "--out-dir", str(out_dir), "--engine", "serial",
                 *SMALL]) == 0
    summary = json.loads((out_dir / SUMMARY_NAME).read_text())
    assert sorted(summary["scenes"]) == ["scene-0001", "scene-0002"]
    assert summary["scenes"]["scene-0001"]["video"] == "scene-0001.mp4"
    for broken in ("[]", '{"scenes": []}'):
        (out_dir / SUMMARY_NAME).write_text(broken)
        assert main(["render", str(scenes_out), "--scenes", "scene-0002", "--out-dir", str(out_dir), "--engine",
                     "serial", "--resume", *SMALL]) == 0
        assert sorted(json.loads((out_dir / SUMMARY_NAME).read_text())["scenes"]) == ["scene-0002"]


def test_the_many_scene_progress_counts_scenes_under_the_jobs_name(scenes_out, tmp_path):
    """One progress task for the job, named for what it does and how many scenes ("render 2 scene(s)"), counting
    scenes to its total; each scene's own render reports under its own name."""
    import nuparquet

    events = []
    nuparquet.render_scenes(scenes_out, None, tmp_path / "v", scenes=["scene-0003", "scene-0001"], scale=0.1,
                            engine=nuparquet.EngineOptions(engine="serial"), on_progress=events.append)
    job = [e for e in events if e.task == "render 2 scene(s)"]
    assert job and {e.total for e in job} == {2} and {e.unit for e in job} == {"scene"}
    assert job[-1].finished and job[-1].done == 2
    assert {e.task for e in events} - {"render 2 scene(s)"} <= {f"render {s} CAM_FRONT" for s in ("scene-0001",
                                                                                                  "scene-0003")}
