"""`nuparquet render OUT --sample | --sample-data | --annotation | --instance | --map ... --out picture.png`: one
picture per call, PNG or JPEG, written atomically; what cannot be drawn is a usage error naming why; lidarseg
predictions are drawn beside the ground truth."""

from __future__ import annotations

import cv2
import numpy as np
import polars as pl
import pytest

import nuparquet
from nuparquet.cli.main import main


@pytest.fixture(scope="module")
def tokens(synth_out):
    ds = nuparquet.open(synth_out)
    sample = ds.scan("tables/sample").collect().row(3, named=True)["token"]
    frames = ds.scan("frames").filter((pl.col("sample_token") == sample) & pl.col("is_key_frame")).collect()
    by_channel = dict(zip(frames["channel"].cast(pl.String).to_list(), frames["token"].to_list()))
    annotations = ds.scan("annotations").filter(pl.col("sample_token") == sample).sort("file_index").collect()
    location = ds.scan("scenes").collect()["log_location"][0]
    node = ds.scan("map/node").filter(pl.col("location") == location).head(1).collect().row(0, named=True)
    lane = ds.scan("map/lane").filter(pl.col("location") == location).head(1).collect()["token"][0]
    return {"sample": sample, **by_channel, "annotation": annotations["token"][0],
            "instance": annotations["instance_token"][0], "location": location, "x": node["x"], "y": node["y"],
            "lane": lane}


def _render(out, *flags, target):
    return main(["render", str(out), *flags, "--out", str(target)])


@pytest.mark.parametrize("case", ["sample", "camera", "lidar", "radar", "pointcloud", "map_in_image", "annotation",
                                  "instance", "patch", "record", "mask", "centerlines", "ego_poses", "next_roads"])
def test_every_picture_is_written_as_png_and_jpeg(synth_out, tokens, tmp_path, case, capsys):
    x, y, loc = tokens["x"], tokens["y"], tokens["location"]
    flags = {
        "sample": ["--sample", tokens["sample"], "--scale", "0.2"],
        "camera": ["--sample-data", tokens["CAM_FRONT"], "--scale", "0.25"],
        "lidar": ["--sample-data", tokens["LIDAR_TOP"], "--nsweeps", "3", "--axes-limit", "30"],
        "radar": ["--sample-data", tokens["RADAR_FRONT"], "--no-underlay-map"],
        "pointcloud": ["--sample", tokens["sample"], "--pointcloud-in-image", "--camera-channel", "CAM_BACK",
                       "--lidar-color", "lidarseg", "--lidarseg-legend", "--scale", "0.25"],
        "map_in_image": ["--sample", tokens["sample"], "--map-in-image", "--scale", "0.25"],
        "annotation": ["--annotation", tokens["annotation"], "--extra-info", "--scale", "0.25"],
        "instance": ["--instance", tokens["instance"], "--instance-annotation", "middle", "--scale", "0.25"],
        "patch": ["--map", loc, "--map-patch", f"{x - 50},{y - 50},{x + 50},{y + 50}"],
        "record": ["--map", loc, "--map-record", f"lane:{tokens['lane']}"],
        "mask": ["--map", loc, "--map-mask", f"{x},{y},60,60", "--map-angle", "30", "--map-layers", "lane,walkway",
                 "--canvas-size", "50,50"],
        "centerlines": ["--map", loc, "--centerlines"],
        "ego_poses": ["--map", loc, "--ego-poses", "--scenes", "scene-0001"],
        "next_roads": ["--map", loc, "--next-roads", f"{x + 0.5},{y + 0.5}"],
    }[case]
    for suffix in (".png", ".jpg"):
        target = tmp_path / f"picture{suffix}"
        code = _render(synth_out, *flags, target=target)
        if case == "next_roads" and code == 2:  # the node may lie on no road: then it says so
            assert "no road_segment, road_block or lane" in capsys.readouterr().err
            return
        assert code == 0, capsys.readouterr().err
        image = cv2.imread(str(target))
        assert image is not None and image.shape[0] > 40 and image.shape[1] > 40 and image.std() > 1
        assert len(np.unique(image.reshape(-1, 3)[::7], axis=0)) > 3  # more than a background
        assert f"-> {target}" in capsys.readouterr().out
        assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no partial left


def test_lidarseg_predictions_are_drawn_beside_the_ground_truth(synth_out, tokens, tmp_path):
    ds = nuparquet.open(synth_out)
    truth_file = ds.scan("tables/lidarseg").filter(pl.col("sample_data_token") == tokens["LIDAR_TOP"]).collect()
    labels = np.fromfile(f"{ds.dataroot}/{truth_file['filename'][0]}", np.uint8)
    manmade_index = ds.scan("tables/category").filter(pl.col("name") == "static.manmade").collect()["index"][0]
    predictions = np.where(labels == np.bincount(labels).argmax(), manmade_index, labels).astype(np.uint8)
    predictions.tofile(tmp_path / "preds.bin")  # the ground predicted as buildings
    assert _render(synth_out, "--sample-data", tokens["LIDAR_TOP"], "--lidar-color", "lidarseg", "--no-underlay-map",
                   "--lidarseg-preds", str(tmp_path / "preds.bin"), target=tmp_path / "seg.png") == 0
    image = cv2.imread(str(tmp_path / "seg.png"))
    assert image.shape == (900, 2 * 900 + 4, 3)
    truth, preds = image[:, :900], image[:, 904:]
    manmade = np.array([135, 184, 222])  # BGR of static.manmade
    assert (truth == manmade).all(axis=2).sum() < 50 < (preds == manmade).all(axis=2).sum()
    short = tmp_path / "short.bin"
    predictions[:-5].tofile(short)
    assert _render(synth_out, "--sample-data", tokens["LIDAR_TOP"], "--lidar-color", "lidarseg",
                   "--lidarseg-preds", str(short), target=tmp_path / "x.png") == 1


@pytest.mark.parametrize("flags, message", [
    (["--sample", "A", "--annotation", "B"], "draw one thing at a time"),
    (["--sample", "A", "--scene", "scene-0001"], "one picture"),
    (["--map-patch", "1,2,3,4"], "give --map LOCATION"),
    (["--map", "boston-seaport"], "draws one map picture"),
    (["--map", "boston-seaport", "--map-patch", "1,2,3"], "takes 4 comma-separated numbers"),
    (["--map", "boston-seaport", "--map-patch", "1,2,a,4"], "takes 4 comma-separated numbers"),
    (["--pointcloud-in-image", "--sample-data", "A"], "give --sample TOKEN"),
    (["--sample-data", "nope"], "no frame (sample_data) 'nope'"),
    (["--annotation", "nope"], "no annotation (sample_annotation) 'nope'"),
    (["--instance", "nope"], "no instance 'nope'"),
    (["--map", "atlantis", "--centerlines"], "no map of 'atlantis'"),
])
def test_what_cannot_be_drawn_is_a_usage_error(synth_out, tmp_path, flags, message, capsys):
    assert _render(synth_out, *flags, target=tmp_path / "x.png") == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_a_picture_needs_a_png_or_jpeg_out(synth_out, tokens, tmp_path, capsys):
    assert main(["render", str(synth_out), "--sample", tokens["sample"]]) == 2
    assert "give --out PICTURE.png" in capsys.readouterr().err
    assert _render(synth_out, "--sample", tokens["sample"], target=tmp_path / "x.mp4") == 2
    assert "written as .png or .jpg" in capsys.readouterr().err


def test_labels_need_a_lidar_keyframe(synth_out, tokens, tmp_path, capsys):
    assert _render(synth_out, "--sample-data", tokens["RADAR_FRONT"], "--lidar-color", "lidarseg",
                   target=tmp_path / "x.png") == 2
    assert "lidarseg labels colour lidar points" in capsys.readouterr().err
    assert _render(synth_out, "--sample-data", tokens["LIDAR_TOP"], "--lidar-color", "lidarseg", "--nsweeps", "2",
                   target=tmp_path / "x.png") == 2
    assert "lidar keyframes only" in capsys.readouterr().err


def test_render_help_names_the_birds_eye_view_and_the_pictures(capsys):
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "bird's-eye view" in text and "--sample-data" in text and "PNG or JPEG" in text
    assert "camera images only" not in text


def test_a_missing_sweep_file_is_named(synth_out, tokens, tmp_path, capsys):
    import os
    from pathlib import Path

    dataroot = Path(nuparquet.open(synth_out).dataroot)
    (tmp_path / "root").mkdir()
    os.symlink(dataroot / "samples", tmp_path / "root" / "samples")  # keyframes only: no sweeps/
    flags = ["--sample-data", tokens["LIDAR_TOP"], "--dataroot", str(tmp_path / "root"), "--no-underlay-map"]
    assert _render(synth_out, *flags, target=tmp_path / "one.png") == 0
    assert _render(synth_out, *flags, "--nsweeps", "3", target=tmp_path / "three.png") == 1
    err = capsys.readouterr().err
    assert "missing point file:" in err and "/sweeps/LIDAR_TOP/" in err and "Traceback" not in err


def test_the_map_lies_under_the_views_from_above_unless_told_not_to(synth_out, tokens):
    """`render_image(sample=...)` and `render_image(sample_data=LIDAR)` (what `render --sample` / `--sample-data`
    draw) lay the map under the lidar and radar views by default (ImageOptions.underlay_map) and not with
    underlay_map=False: the views from above differ, the cameras do not."""
    from nuparquet.rendering.pictures.single import render_image

    ds = nuparquet.open(synth_out)
    with_map = render_image(ds, sample=tokens["sample"], scale=0.2)
    without = render_image(ds, sample=tokens["sample"], scale=0.2, underlay_map=False)
    width, height = 1600 // 5, 900 // 5  # the tiles: the synthetic cameras at scale 0.2
    assert with_map.shape == without.shape == (3 * height, 3 * width, 3)
    assert np.array_equal(with_map[height:], without[height:])  # the camera rows
    assert (with_map[:height] != without[:height]).any(axis=2).sum() > 500
    # and a lidar frame alone (`render --sample-data`), seen from above likewise
    with_map = render_image(ds, sample_data=tokens["LIDAR_TOP"])
    without = render_image(ds, sample_data=tokens["LIDAR_TOP"], underlay_map=False)
    assert with_map.shape == without.shape and (with_map != without).any(axis=2).sum() > 500


def test_a_sample_picture_reads_its_files_from_the_dataroot_given(synth_out, tokens, tmp_path):
    """`render_image` of a dataset opened with `dataroot=` (what `render --sample --dataroot` draws) reads the sample's files
    under the dataroot given, not the one the conversion recorded: an empty one lacks them, and the error names a
    file under it; a dataroot holding the same files gives the same picture."""
    import os
    from pathlib import Path

    from nuparquet.errors import InputError
    from nuparquet.rendering.pictures.single import render_image

    ds = nuparquet.open(synth_out)
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match=str(tmp_path / "empty")):
        render_image(nuparquet.open(synth_out, dataroot=tmp_path / "empty"), sample=tokens["sample"], scale=0.2,
                     nsweeps=1)
    (tmp_path / "copy").mkdir()
    recorded = Path(ds.dataroot)
    for folder in ("samples", "sweeps", "maps"):
        if (recorded / folder).exists():
            os.symlink(recorded / folder, tmp_path / "copy" / folder)
    assert np.array_equal(render_image(nuparquet.open(synth_out, dataroot=tmp_path / "copy"), sample=tokens["sample"],
                                       scale=0.2),
                          render_image(ds, sample=tokens["sample"], scale=0.2))


def test_the_extra_info_band_holds_seven_lines_of_28_pixels(synth_out, tokens, tmp_path):
    # the devkit's extra_info: category, lidar and radar points, distance, width, length, height
    plain, extra = tmp_path / "plain.png", tmp_path / "extra.png"
    assert _render(synth_out, "--annotation", tokens["annotation"], "--scale", "0.25", target=plain) == 0
    assert _render(synth_out, "--annotation", tokens["annotation"], "--scale", "0.25", "--extra-info",
                   target=extra) == 0
    without, with_band = cv2.imread(str(plain)), cv2.imread(str(extra))
    assert with_band.shape[1] == without.shape[1]
    assert with_band.shape[0] - without.shape[0] == 7 * 28 + 12


def test_ego_poses_on_the_map_are_those_of_the_scenes_named(map_out, tmp_path, capsys):
    ds = nuparquet.open(map_out)
    scenes = ds.scan("scenes").select("name", "token", "log_location").sort("name").collect()
    loc = scenes.group_by("log_location").len().filter(pl.col("len") >= 2).sort("log_location")["log_location"][0]
    here = scenes.filter(pl.col("log_location") == loc)
    pictures = {}
    for name, flags in (("one", ["--scenes", here["name"][0]]), ("all", [])):
        code = _render(map_out, "--map", loc, "--ego-poses", *flags, target=tmp_path / f"{name}.png")
        assert code == 0, capsys.readouterr().err
        pictures[name] = cv2.imread(str(tmp_path / f"{name}.png"))
    from nuparquet.rendering.pictures.single import render_egoposes_on_map

    assert np.array_equal(pictures["one"], render_egoposes_on_map(ds, loc, [here["token"][0]])[:, :, ::-1])
    assert np.array_equal(pictures["all"], render_egoposes_on_map(ds, loc, None)[:, :, ::-1])
    assert not np.array_equal(pictures["one"], pictures["all"])  # the other scene's poses are left out
