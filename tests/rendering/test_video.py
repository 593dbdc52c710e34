"""Videos and image folders written by `nuparquet render`, decoded back with PyAV; missing image files; CLI
errors. The expected frame counts come straight from the frames dataset, not from the renderer."""

from __future__ import annotations

import os
from pathlib import Path

import av
import numpy as np
import polars as pl
import pytest

import nuparquet
from nuparquet.cli.main import main
from nuparquet.rendering.video.video import VideoWriter


def _probe(path: Path) -> dict:
    """Codec, pixel format, size and the number of decoded frames of a video file."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames = sum(1 for _ in container.decode(stream))
        return {
            "codec": stream.codec_context.name,
            "pix_fmt": stream.codec_context.pix_fmt,
            "size": (stream.codec_context.width, stream.codec_context.height),
            "frames": frames,
            "rate": float(stream.average_rate),
        }


def _camera_frames(out: Path, scene: str, channel: str, keyframes_only: bool) -> pl.DataFrame:
    frames = nuparquet.open(out).scan("frames").filter(
        pl.col("scene_name") == scene, pl.col("channel").cast(pl.String) == channel
    )
    if keyframes_only:
        frames = frames.filter(pl.col("is_key_frame"))
    return frames.sort("timestamp").collect()


def _first_scene(out: Path) -> str:
    return nuparquet.open(out).scan("scenes").select("name").collect()["name"].sort()[0]


# --- the writer ----------------------------------------------------------------------------------------------


def test_video_writer_pads_odd_sizes_and_writes_browser_playable_h264(tmp_path):
    path = tmp_path / "odd.mp4"
    rng = np.random.default_rng(0)
    with VideoWriter(path, width=101, height=51, fps=12) as video:
        for _ in range(5):
            video.write(rng.integers(0, 255, (51, 101, 3), dtype=np.uint8))
    info = _probe(path)
    assert info == {"codec": "h264", "pix_fmt": "yuv420p", "size": (102, 52), "frames": 5, "rate": 12.0}
    head = path.read_bytes()[:4096]
    assert head.find(b"moov") != -1 and (head.find(b"mdat") == -1 or head.find(b"moov") < head.find(b"mdat"))


def test_video_writer_rejects_frames_of_another_size(tmp_path):
    with pytest.raises(ValueError, match="64x48"):
        with VideoWriter(tmp_path / "x.mp4", width=64, height=48) as video:
            video.write(np.zeros((50, 50, 3), np.uint8))
    assert not (tmp_path / "x.mp4").exists()


# --- renders of the synthetic dataset ------------------------------------------------------------------------


def test_keyframe_video_has_one_frame_per_keyframe(synth_out, tmp_path):
    scene = _first_scene(synth_out)
    out = tmp_path / "scene.mp4"
    assert main(["render", str(synth_out), "--scene", scene, "--channel", "CAM_FRONT", "--out", str(out), "--quiet"]) == 0
    expected = _camera_frames(synth_out, scene, "CAM_FRONT", keyframes_only=True).height
    assert expected > 0
    assert _probe(out) == {"codec": "h264", "pix_fmt": "yuv420p", "size": (800, 450), "frames": expected, "rate": 2.0}


def test_all_frames_video_has_one_frame_per_camera_frame(synth_out, tmp_path):
    scene = _first_scene(synth_out)
    out = tmp_path / "all.mp4"
    code = main(["render", str(synth_out), "--scene", scene, "--channel", "CAM_BACK", "--all-frames", "--out", str(out),
                 "--scale", "0.25", "--quiet"])
    assert code == 0
    frames = _camera_frames(synth_out, scene, "CAM_BACK", keyframes_only=False)
    assert frames.filter(~pl.col("is_key_frame")).height > 0  # the synthetic data has sweeps
    assert _probe(out) == {"codec": "h264", "pix_fmt": "yuv420p", "size": (400, 226), "frames": frames.height, "rate": 12.0}


def test_frames_dir_writes_one_image_per_frame(synth_out, tmp_path):
    scene = _first_scene(synth_out)
    frames_dir = tmp_path / "frames"
    code = main(["render", str(synth_out), "--scene", scene, "--channel", "CAM_FRONT_LEFT", "--frames-dir", str(frames_dir),
                 "--frame-format", "png", "--labels", "track", "--lidar", "--quiet"])
    assert code == 0
    expected = _camera_frames(synth_out, scene, "CAM_FRONT_LEFT", keyframes_only=True).height
    written = sorted(frames_dir.iterdir())
    assert [p.name for p in written] == [f"{i:05d}.png" for i in range(expected)] + ["frames.parquet"]
    written = written[:-1]
    import cv2

    assert cv2.imread(str(written[0])).shape == (450, 800, 3)


def test_mosaic_tiles_six_cameras_three_by_two(synth_out, tmp_path):
    scene = _first_scene(synth_out)
    out = tmp_path / "mosaic.mp4"
    code = main(["render", str(synth_out), "--scene", scene, "--channel", "all", "--out", str(out), "--scale", "0.2",
                 "--quiet"])
    assert code == 0
    samples = _camera_frames(synth_out, scene, "CAM_FRONT", keyframes_only=True).height
    info = _probe(out)
    assert info["size"] == (3 * 320, 2 * 180)
    assert info["frames"] == samples  # keyframes: one picture per sample


def test_mosaic_all_frames_uses_devkit_time_steps(synth_out, tmp_path):
    scene = _first_scene(synth_out)
    out = tmp_path / "mosaic-all.mp4"
    assert main(["render", str(synth_out), "--scene", scene, "--channel", "all", "--all-frames", "--out", str(out),
                 "--scale", "0.1", "--quiet"]) == 0
    keyframes = _camera_frames(synth_out, scene, "CAM_FRONT", keyframes_only=True)
    samples = nuparquet.open(synth_out).scan("tables/sample").filter(
        pl.col("scene_token") == keyframes["scene_token"][0]
    ).collect()
    first, last = samples["timestamp"].min(), samples["timestamp"].max()
    steps, t = 0, float(first)
    while t < last:  # devkit render_scene's loop, at 12 Hz
        t += 1 / 12 * 1e6
        steps += 1
    info = _probe(out)
    assert info["frames"] == steps
    assert info["size"] == (3 * 160, 2 * 90)


# --- missing images ------------------------------------------------------------------------------------------


@pytest.fixture()
def partial_dataroot(synth_out, tmp_path) -> tuple[Path, str, Path]:
    """A dataroot with every CAM_FRONT keyframe image of the first scene but one (symlinks)."""
    ds = nuparquet.open(synth_out)
    scene = _first_scene(synth_out)
    frames = _camera_frames(synth_out, scene, "CAM_FRONT", keyframes_only=True)
    root = tmp_path / "partial"
    names = frames["filename"].to_list()
    for name in names[:2] + names[3:]:
        target = root / name
        target.parent.mkdir(parents=True, exist_ok=True)
        os.symlink(Path(ds.dataroot) / name, target)
    return root, scene, root / names[2]


def test_missing_image_with_on_missing_error_exits_1_naming_the_file(partial_dataroot, synth_out, tmp_path, capsys):
    root, scene, absent = partial_dataroot
    out = tmp_path / "x.mp4"
    code = main(["render", str(synth_out), "--scene", scene, "--out", str(out), "--dataroot", str(root),
                 "--on-missing", "error", "--quiet"])
    assert code == 1
    assert str(absent) in capsys.readouterr().err
    assert not out.exists()  # no truncated video left behind


def test_missing_image_is_skipped_with_a_warning_count(partial_dataroot, synth_out, tmp_path, capsys):
    root, scene, absent = partial_dataroot
    out = tmp_path / "x.mp4"
    code = main(["render", str(synth_out), "--scene", scene, "--out", str(out), "--dataroot", str(root), "--quiet"])
    assert code == 0
    err = capsys.readouterr().err
    assert "warning: 1 file(s) missing" in err and str(absent) in err
    # every keyframe keeps its place in time: the missing one repeats the picture before
    expected = _camera_frames(synth_out, scene, "CAM_FRONT", keyframes_only=True).height
    assert _probe(out)["frames"] == expected


def test_corrupt_image_counts_as_unreadable(partial_dataroot, synth_out, tmp_path, capsys):
    root, scene, absent = partial_dataroot
    absent.write_bytes(b"not a jpeg")
    code = main(["render", str(synth_out), "--scene", scene, "--frames-dir", str(tmp_path / "f"), "--dataroot", str(root),
                 "--on-missing", "error", "--quiet"])
    assert code == 1
    assert str(absent) in capsys.readouterr().err


# --- the real extract (no sweeps/ folder) --------------------------------------------------------------------


@pytest.mark.real
def test_real_extract_keyframe_video(extract_out, tmp_path):
    out = tmp_path / "scene-0916.mp4"
    assert main(["render", str(extract_out), "--scene", "scene-0916", "--out", str(out), "--quiet"]) == 0
    expected = _camera_frames(extract_out, "scene-0916", "CAM_FRONT", keyframes_only=True).height
    assert _probe(out) == {"codec": "h264", "pix_fmt": "yuv420p", "size": (800, 450), "frames": expected, "rate": 2.0}


@pytest.mark.real
def test_real_extract_all_frames_reports_the_missing_sweeps(extract_out, tmp_path, capsys):
    out = tmp_path / "all.mp4"
    args = ["render", str(extract_out), "--scene", "scene-0916", "--all-frames", "--out", str(out), "--scale", "0.25", "--quiet"]
    assert main(args) == 0
    err = capsys.readouterr().err
    frames = _camera_frames(extract_out, "scene-0916", "CAM_FRONT", keyframes_only=False)
    sweeps = frames.filter(~pl.col("is_key_frame")).height
    assert f"warning: {sweeps} file(s) missing" in err and "sweeps/CAM_FRONT/" in err
    # the true timing: one video frame per camera frame at 12 Hz, the missing sweeps repeating the keyframe before
    # (the frames before the first keyframe: a placeholder)
    assert _probe(out)["frames"] == frames.height
    index = pl.read_parquet(tmp_path / "all.frames.parquet")
    assert index["sample_data_token"].to_list() == frames.sort("timestamp")["token"].to_list()
    assert index["drawn"].to_list() == frames.sort("timestamp")["is_key_frame"].to_list()
    first = index["drawn"].arg_max()
    shown = index["shows_frame"].to_list()
    assert all(shown[i] == (i if drawn else max((j for j in range(first, i) if index["drawn"][j]), default=0))
               for i, drawn in enumerate(index["drawn"].to_list()))

    assert main(args + ["--on-missing", "error"]) == 1
    assert "sweeps/CAM_FRONT/" in capsys.readouterr().err


# --- usage errors --------------------------------------------------------------------------------------------


def test_unknown_scene_is_a_usage_error_listing_the_scenes(synth_out, tmp_path, capsys):
    code = main(["render", str(synth_out), "--scene", "scene-nope", "--out", str(tmp_path / "x.mp4")])
    assert code == 2
    assert f"valid scenes: {_first_scene(synth_out)}" in capsys.readouterr().err


def test_unknown_channel_is_a_usage_error_listing_the_cameras(synth_out, tmp_path, capsys):
    code = main(["render", str(synth_out), "--scene", _first_scene(synth_out), "--channel", "LIDAR_TOP",
                 "--out", str(tmp_path / "x.mp4")])
    assert code == 2
    assert "CAM_FRONT" in capsys.readouterr().err


def test_render_needs_an_output(synth_out, capsys):
    assert main(["render", str(synth_out), "--scene", _first_scene(synth_out)]) == 2
    assert "--out" in capsys.readouterr().err
