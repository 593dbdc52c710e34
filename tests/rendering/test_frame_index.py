"""The frame index of a scene render (issue 24): `frames.parquet` in --frames-dir and `<video>.frames.parquet` beside
the video name the sample_data each output picture shows, per tile; an all-frames render whose sweep images are
missing keeps one picture per output time, repeating the picture before and saying so."""

from __future__ import annotations

import os
from pathlib import Path

import av
import polars as pl
import pytest

import nuparquet
from nuparquet.cli.main import main

SCENE = "scene-0001"


def _frames(out, channel=None, keyframes=True):
    lf = nuparquet.open(out).scan("frames").filter(pl.col("scene_name") == SCENE)
    if channel:
        lf = lf.filter(pl.col("channel").cast(pl.String) == channel)
    if keyframes:
        lf = lf.filter(pl.col("is_key_frame"))
    return lf.with_columns(pl.col("channel").cast(pl.String)).sort("timestamp").collect()


def _video_frames(path: Path) -> int:
    with av.open(str(path)) as container:
        return sum(1 for _ in container.decode(video=0))


def test_one_camera_index_names_each_frame_in_time_order(synth_out, tmp_path):
    assert main(["render", str(synth_out), "--scene", SCENE, "--channel", "CAM_BACK", "--scale", "0.1",
                 "--out", str(tmp_path / "v.mp4"), "--frames-dir", str(tmp_path / "f"), "--quiet"]) == 0
    expected = _frames(synth_out, "CAM_BACK")
    for index in (pl.read_parquet(tmp_path / "f" / "frames.parquet"), pl.read_parquet(tmp_path / "v.frames.parquet")):
        assert index["frame"].to_list() == list(range(expected.height))
        assert index["sample_data_token"].to_list() == expected["token"].to_list()
        assert index["timestamp"].to_list() == expected["timestamp"].to_list() == index["time_us"].to_list()
        assert set(index["channel"]) == {"CAM_BACK"} and index["drawn"].all()
        assert index["shows_frame"].to_list() == index["frame"].to_list()
        assert dict(index.schema) == {  # the file's declared types, not those polars would infer
            "frame": pl.Int32, "time_us": pl.Int64, "tile": pl.Int16, "channel": pl.String,
            "sample_data_token": pl.String, "timestamp": pl.Int64, "drawn": pl.Boolean, "shows_frame": pl.Int32}
    assert len(list((tmp_path / "f").glob("*.jpg"))) == _video_frames(tmp_path / "v.mp4") == expected.height


def test_mosaic_index_has_every_tile_of_each_picture_from_one_sample(synth_out, tmp_path):
    assert main(["render", str(synth_out), "--scene", SCENE, "--channel", "all", "--bev", "--scale", "0.1",
                 "--frames-dir", str(tmp_path / "f"), "--quiet"]) == 0
    index = pl.read_parquet(tmp_path / "f" / "frames.parquet")
    layout = nuparquet.open(synth_out).channels["camera_layout"]
    tiles = [c for c in layout[0]] + ["BEV"] + [c for row in layout[1:] for c in row]
    keyframes = _frames(synth_out)
    sample_of = dict(zip(keyframes["token"].to_list(), keyframes["sample_token"].to_list()))
    assert index.height == len(tiles) * keyframes["sample_token"].n_unique()
    for frame, rows in index.group_by("frame", maintain_order=True):
        rows = rows.sort("tile")
        assert rows["channel"].to_list() == tiles
        assert len({sample_of[t] for t in rows["sample_data_token"].to_list()}) == 1  # one sample per picture
        bev = rows.filter(pl.col("channel") == "BEV").row(0, named=True)
        lidar = keyframes.filter(pl.col("token") == bev["sample_data_token"])
        assert lidar["channel"].item() == "LIDAR_TOP"


@pytest.fixture()
def keyframes_only_root(synth_out, tmp_path):
    """The dataroot with only the keyframe images of CAM_FRONT (its sweeps missing, as in a partial download)."""
    root = tmp_path / "partial"
    dataroot = Path(nuparquet.open(synth_out).dataroot)
    for name in _frames(synth_out, "CAM_FRONT")["filename"].to_list():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        os.symlink(dataroot / name, root / name)
    return root


def test_all_frames_with_missing_sweeps_keep_the_true_timing(synth_out, keyframes_only_root, tmp_path, capsys):
    out = tmp_path / "all.mp4"
    assert main(["render", str(synth_out), "--scene", SCENE, "--all-frames", "--scale", "0.1", "--out", str(out),
                 "--dataroot", str(keyframes_only_root), "--quiet"]) == 0
    frames = _frames(synth_out, "CAM_FRONT", keyframes=False)
    sweeps = frames.filter(~pl.col("is_key_frame")).height
    assert sweeps > 10 and f"{sweeps} frame(s) skipped" in capsys.readouterr().err
    assert _video_frames(out) == frames.height  # picture n at n / 12 s, as the camera's frames are
    index = pl.read_parquet(tmp_path / "all.frames.parquet")
    assert index["sample_data_token"].to_list() == frames["token"].to_list()
    assert index["drawn"].to_list() == frames["is_key_frame"].to_list()
    last_drawn = 0
    for row in index.iter_rows(named=True):
        last_drawn = row["frame"] if row["drawn"] else last_drawn
        assert row["shows_frame"] == last_drawn  # a missing sweep repeats the keyframe before it


def test_a_render_with_nothing_to_show_writes_no_index(synth_out, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    code = main(["render", str(synth_out), "--scene", SCENE, "--out", str(tmp_path / "v.mp4"), "--frames-dir",
                 str(tmp_path / "f"), "--dataroot", str(tmp_path / "empty"), "--quiet"])
    assert code == 1 and "no frame of scene-0001" in capsys.readouterr().err
    assert not (tmp_path / "v.mp4").exists() and not (tmp_path / "v.frames.parquet").exists()
    assert not (tmp_path / "f").exists()
