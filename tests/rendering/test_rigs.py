"""Rendering a dataset whose sensors are not nuScenes': a Lyft Level 5-like rig with seven cameras (a zoomed
front camera among them, two image sizes) and three lidars. `--channel all` must tile every camera where the
layout says, and `--lidar` must draw the reference lidar's points (LIDAR_TOP), checked against the devkit."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import polars as pl
import pytest

import nuparquet
from conftest import LYFT_RIG_VERSION
from nuparquet.cli.main import main

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit's explorer imports pyplot; never open a window

FRONT = {"CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_ZOOMED", "CAM_FRONT_RIGHT"}
BACK = ["CAM_BACK_LEFT", "CAM_BACK", "CAM_BACK_RIGHT"]
SCALE = 0.1


def _scene(out: Path) -> str:
    return nuparquet.open(out).scan("scenes").select("name").collect()["name"].sort()[0]


def _keyframe_paths(out: Path, scene: str) -> dict[tuple[str, str], Path]:
    """(sample_token, channel) -> image file of every keyframe camera frame of the scene."""
    ds = nuparquet.open(out)
    frames = ds.scan("frames").filter(pl.col("scene_name") == scene, pl.col("is_key_frame"),
                                      pl.col("modality").cast(pl.String) == "camera").collect()
    return {(row["sample_token"], str(row["channel"])): Path(ds.dataroot) / row["filename"]
            for row in frames.iter_rows(named=True)}


def _samples(out: Path, scene: str) -> list[str]:
    ds = nuparquet.open(out)
    scene_token = ds.scan("scenes").filter(pl.col("name") == scene).select("token").collect().item()
    return ds.scan("tables/sample").filter(pl.col("scene_token") == scene_token).sort("timestamp").collect()[
        "token"].to_list()


def test_the_rig_has_seven_cameras_and_three_lidars(lyft_rig_out):
    facts = nuparquet.open(lyft_rig_out).channels
    assert set(facts["cameras"]) == FRONT | set(BACK)
    assert facts["lidars"] == ["LIDAR_FRONT_LEFT", "LIDAR_FRONT_RIGHT", "LIDAR_TOP"]
    assert facts["reference_lidar"] == "LIDAR_TOP" and facts["radars"] == []
    front, back = facts["camera_layout"]
    # Front row left to right: the left camera first, the right one last, the two forward ones between.
    assert set(front) == FRONT and front[0] == "CAM_FRONT_LEFT" and front[-1] == "CAM_FRONT_RIGHT"
    assert back == BACK


def test_channel_all_tiles_every_camera_where_the_layout_says(lyft_rig_out, tmp_path):
    scene = _scene(lyft_rig_out)
    frames_dir = tmp_path / "frames"
    assert main(["render", str(lyft_rig_out), "--scene", scene, "--channel", "all", "--frames-dir", str(frames_dir),
                 "--frame-format", "png", "--scale", str(SCALE), "--labels", "none", "--quiet"]) == 0
    # Tiles are the largest image (2048 x 1024: the zoomed camera's width, the others' height) scaled.
    tile_w, tile_h = round(2048 * SCALE), round(1024 * SCALE)
    layout = nuparquet.open(lyft_rig_out).channels["camera_layout"]
    samples = _samples(lyft_rig_out, scene)
    paths = _keyframe_paths(lyft_rig_out, scene)
    pictures = sorted(frames_dir.glob("*.png"))
    assert len(pictures) == len(samples)  # keyframes: one picture per sample

    distances = {}  # (tile camera, image camera) -> summed mean absolute difference over the outputs
    for sample, picture_path in zip(samples, pictures):
        picture = cv2.imread(str(picture_path)).astype(np.float64)
        assert picture.shape == (2 * tile_h, 4 * tile_w, 3)
        images = {channel: cv2.resize(cv2.imread(str(paths[sample, channel])), (tile_w, tile_h),
                                      interpolation=cv2.INTER_AREA).astype(np.float64)
                  for channel in FRONT | set(BACK)}
        for row, cameras in enumerate(layout):
            offset = (4 - len(cameras)) * tile_w // 2  # the back row of three is centred
            for column, camera in enumerate(cameras):
                x, y = offset + column * tile_w, row * tile_h
                tile = picture[y:y + tile_h, x:x + tile_w]
                assert tile.mean() > 60  # a camera image (light sky and ground), not black
                for channel, image in images.items():
                    distances[camera, channel] = distances.get((camera, channel), 0.0) + np.abs(tile - image).mean()
        # The back row leaves half a tile black at each end.
        assert picture[tile_h:, : tile_w // 2].max() == 0 and picture[tile_h:, -(tile_w // 2):].max() == 0
    for camera in FRONT | set(BACK):
        own = distances[camera, camera]
        others = min(value for (tile, channel), value in distances.items() if tile == camera and channel != camera)
        assert own < 0.5 * others, (camera, own, others)


def _changed_pixels(with_points: Path, without: Path) -> np.ndarray:
    """(N, 2) [u, v] of the pixels that differ between two renders of one frame."""
    a, b = cv2.imread(str(with_points)).astype(int), cv2.imread(str(without)).astype(int)
    v, u = np.nonzero(np.abs(a - b).max(axis=2) > 0)
    return np.stack([u, v], axis=1)


@pytest.mark.devkit
def test_lidar_draws_the_reference_lidar_points_where_the_devkit_projects_them(lyft_rig_root, lyft_rig_out, devkit,
                                                                               tmp_path):
    scene = _scene(lyft_rig_out)
    common = ["render", str(lyft_rig_out), "--scene", scene, "--channel", "CAM_FRONT", "--scale", "0.5",
              "--labels", "none", "--frame-format", "png", "--quiet"]
    assert main([*common, "--frames-dir", str(tmp_path / "plain")]) == 0
    assert main([*common, "--frames-dir", str(tmp_path / "lidar"), "--lidar"]) == 0
    changed = _changed_pixels(tmp_path / "lidar" / "00000.png", tmp_path / "plain" / "00000.png")
    assert len(changed) > 100

    nusc = devkit.NuScenes(version=LYFT_RIG_VERSION, dataroot=str(lyft_rig_root), verbose=False)
    sample = nusc.get("sample", _samples(lyft_rig_out, scene)[0])

    def devkit_points_px(lidar_channel: str) -> np.ndarray:
        points, _, _ = nusc.explorer.map_pointcloud_to_image(sample["data"][lidar_channel], sample["data"]["CAM_FRONT"])
        return points[:2].T * 0.5 + (0.5 - 1.0) / 2.0  # full-size pixels -> the half-size output (pixel centres)

    def near(a: np.ndarray, b: np.ndarray, radius_px: float) -> float:
        """Share of the points of `a` with a point of `b` within `radius_px` (max norm)."""
        if len(a) == 0 or len(b) == 0:
            return 0.0
        hits = [np.any(np.abs(b - p).max(axis=1) <= radius_px) for p in a]
        return float(np.mean(hits))

    top = devkit_points_px("LIDAR_TOP")
    assert len(top) > 20
    # Every drawn pixel belongs to a 2x2 square at a LIDAR_TOP point, and nearly every point was drawn (a few
    # may hide under a box edge drawn on top).
    assert near(changed, top, 1.5) > 0.99
    assert near(top, changed, 1.0) > 0.9
    # The other lidars' points are elsewhere: the check tells the lidars apart.
    for other in ("LIDAR_FRONT_LEFT", "LIDAR_FRONT_RIGHT"):
        assert near(changed, devkit_points_px(other), 1.5) < 0.5


@pytest.fixture(scope="module")
def no_camera_out(synth_root, tmp_path_factory) -> Path:
    """The synthetic set without its cameras (their sensors, calibrations and frames taken out of the JSON tables:
    a lidar and radar rig), converted."""
    import json
    import shutil

    from conftest import SYNTH_VERSION

    base = tmp_path_factory.mktemp("no-camera")
    root = base / "data"
    shutil.copytree(synth_root, root, copy_function=os.symlink)

    def rewrite(name, keep):
        path = root / SYNTH_VERSION / f"{name}.json"
        records = [r for r in json.loads(path.read_text()) if keep(r)]
        path.unlink()
        path.write_text(json.dumps(records))
        return records

    sensors = {r["token"] for r in rewrite("sensor", lambda r: r["modality"] != "camera")}
    calibrations = {r["token"] for r in rewrite("calibrated_sensor", lambda r: r["sensor_token"] in sensors)}
    rewrite("sample_data", lambda r: r["calibrated_sensor_token"] in calibrations)
    nuparquet.convert(root, SYNTH_VERSION, base / "out", workers=1)
    return base / "out"


@pytest.mark.parametrize("channel", [None, "all"])
def test_a_rig_without_cameras_has_no_camera_to_render(no_camera_out, channel, tmp_path):
    """The default camera and `--channel all` of a dataset with no camera: a usage error saying so, no video."""
    ds = nuparquet.open(no_camera_out)
    assert ds.channels["cameras"] == [] and ds.channels["reference_lidar"] == "LIDAR_TOP"
    with pytest.raises(nuparquet.UsageError, match="^the dataset has no camera to render$"):
        nuparquet.render(ds, _scene(no_camera_out), channel=channel, out=tmp_path / "v.mp4", scale=SCALE)
    assert not (tmp_path / "v.mp4").exists()
