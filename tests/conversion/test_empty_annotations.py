"""A version whose annotation tables are empty (like nuScenes v1.0-test): it converts, its derived datasets
count 0 annotations (not null), stats run, and renders show the camera images without boxes. Expectations
come from the devkit reading the same JSON and from the source JPEGs."""

from __future__ import annotations


import cv2
import numpy as np
import polars as pl
import pytest

from nuparquet.cli.main import main
from conftest import IRREGULAR_EMPTY_VERSION


def read(out, dataset: str) -> pl.DataFrame:
    return pl.read_parquet(out / dataset / "*.parquet")


@pytest.fixture(scope="module")
def nusc(devkit, irregular_root):
    return devkit.NuScenes(version=IRREGULAR_EMPTY_VERSION, dataroot=str(irregular_root), verbose=False)


def test_derived_datasets_count_zero_annotations_not_null(nusc, irregular_empty_out):
    assert len(nusc.sample_annotation) == 0 and len(nusc.instance) == 0
    scenes = read(irregular_empty_out, "scenes")
    assert sorted(scenes["name"].to_list()) == sorted(s["name"] for s in nusc.scene)
    assert scenes["num_annotations"].to_list() == [0] * len(nusc.scene)
    assert scenes["num_instances"].to_list() == [0] * len(nusc.scene)
    assert read(irregular_empty_out, "annotations").height == 0
    assert read(irregular_empty_out, "instances").height == 0
    frames = read(irregular_empty_out, "frames")
    assert frames.height == len(nusc.sample_data)
    assert set(frames["token"].to_list()) == {sd["token"] for sd in nusc.sample_data}


def test_stats_run_and_report_no_annotations(irregular_empty_out, nusc, capsys):
    assert main(["stats", str(irregular_empty_out), "--format", "json", "--only", "scenes",
                 "--only", "class_distribution"]) == 0
    text = capsys.readouterr().out
    assert all(s["name"] in text for s in nusc.scene)
    assert main(["stats", str(irregular_empty_out)]) == 0  # every default section, on empty annotations


def test_render_without_boxes_shows_the_camera_images_unchanged(irregular_empty_out, irregular_root, nusc,
                                                                 tmp_path):
    scene = sorted(s["name"] for s in nusc.scene)[1]
    frames_dir = tmp_path / "frames"
    code = main(["render", str(irregular_empty_out), "--scene", scene, "--channel", "CAM_FRONT", "--frames-dir",
                 str(frames_dir), "--frame-format", "png", "--scale", "0.25", "--quiet"])
    assert code == 0
    scene_rec = next(s for s in nusc.scene if s["name"] == scene)
    expected, token = [], scene_rec["first_sample_token"]
    while token:  # the devkit's keyframe walk: CAM_FRONT of every sample, in order
        sample = nusc.get("sample", token)
        expected.append(nusc.get("sample_data", sample["data"]["CAM_FRONT"])["filename"])
        token = sample["next"]
    written = sorted(frames_dir.glob("*.png"))  # and frames.parquet, the frame index
    assert len(written) == len(expected)
    for path, filename in zip(written, expected):
        image = cv2.imread(str(path))
        reference = cv2.resize(cv2.imread(str(irregular_root / filename)), image.shape[1::-1],
                               interpolation=cv2.INTER_AREA)
        # No overlay: only resampling differences (reduced JPEG decoding); a drawn box edge differs by ~100 levels.
        difference = np.abs(image.astype(int) - reference.astype(int))
        assert np.percentile(difference, 99.9) < 25 and difference.mean() < 2, filename
