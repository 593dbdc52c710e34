"""`render --lidar-predictions`: a lidarseg or panoptic submission's labels colour the points of a scene video
instead of the ground truth, in the colours of the devkit's challenge classes (`LidarsegClassMapper
.get_coarse2color`), thing instances in the devkit's panoptic colour table; and what it cannot draw is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main
from nuparquet.errors import InputError, UsageError
from nuparquet.rendering.points import CloudReader

CAR = 4  # the challenge class "car"


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    from nuparquet.conversion import convert
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path_factory.mktemp("preds") / "data", scenes=1, samples_per_scene=3, with_images=True,
                      with_lidar=True, seed=4, version=SYNTH_VERSION, with_can_bus=False)
    out = tmp_path_factory.mktemp("preds-out") / "out"
    convert(root, SYNTH_VERSION, out, sensors=("lidar",), workers=1)
    return root, out


@pytest.fixture(scope="module")
def devkit_nusc(labelled):
    from nuscenes.nuscenes import NuScenes

    return NuScenes(SYNTH_VERSION, str(labelled[0]), verbose=False)


@pytest.fixture(scope="module")
def submission(labelled, devkit_nusc, tmp_path_factory) -> Path:
    """The ground truth mapped to the challenge classes by the devkit's mapper, every third point predicted car."""
    from nuscenes.eval.lidarseg.utils import LidarsegClassMapper

    root, _ = labelled
    mapper = LidarsegClassMapper(devkit_nusc)
    folder = tmp_path_factory.mktemp("preds-sub") / "results"
    (folder / "lidarseg" / "mini_val").mkdir(parents=True)
    for sample in devkit_nusc.sample:
        token = sample["data"]["LIDAR_TOP"]
        labels = np.fromfile(root / devkit_nusc.get("lidarseg", token)["filename"], dtype=np.uint8)
        pred = mapper.convert_label(labels)
        pred[::3] = CAR
        pred.astype(np.uint8).tofile(folder / "lidarseg" / "mini_val" / f"{token}_lidarseg.bin")
    return folder


def _keyframe_lidar(out) -> pl.DataFrame:
    import nuparquet

    return (nuparquet.open(out).scan("frames").filter(pl.col("is_key_frame") & (pl.col("channel") == "LIDAR_TOP"))
            .sort("timestamp").collect())


def test_points_take_the_devkits_challenge_colour_of_their_predicted_class(labelled, devkit_nusc, submission):
    import nuparquet
    from nuscenes.eval.lidarseg.utils import LidarsegClassMapper

    root, out = labelled
    mapper = LidarsegClassMapper(devkit_nusc)
    idx2name = {index: name for name, index in mapper.coarse_name_2_coarse_idx_mapping.items()}
    lidar = _keyframe_lidar(out)
    reader = CloudReader.build(lidar, root, dataset=nuparquet.open(out), color="lidarseg", predictions=submission)
    for row, token in enumerate(lidar["token"].to_list()):
        points, labels = reader.cloud(row)
        expected = np.fromfile(submission / "lidarseg" / "mini_val" / f"{token}_lidarseg.bin", dtype=np.uint8)
        assert np.array_equal(labels, expected) and len(points) == len(expected)
        every = np.arange(len(points))
        rgb = reader.colors_bgr(points, labels, every)[:, ::-1]
        assert rgb.tolist() == [list(mapper.coarse_colormap[idx2name[c]]) for c in expected.tolist()]
        assert rgb[0].tolist() == [255, 158, 0]  # car, orange
        kept = every[1::2]
        assert np.array_equal(reader.colors_bgr(points, labels, kept), reader.colors_bgr(points, labels, every)[kept])


def test_panoptic_predictions_colour_things_per_instance_and_stuff_by_class():
    from nuscenes.panoptic.panoptic_utils import generate_panoptic_colors
    from nuscenes.utils.color_map import get_colormap

    from nuparquet.rendering.point_colors import challenge_label_rgb

    name2idx = {name: index for index, name in enumerate(get_colormap())}
    state = np.random.get_state()
    table = generate_panoptic_colors(get_colormap(), name2idx)
    np.random.set_state(state)
    # car instances 1 and 2, pedestrian 1 (class 7), the last thing class (10, truck), the first stuff class (11,
    # driveable_surface), vegetation (16), ignore (0), a class outside the 16
    labels = np.array([4001, 4002, 7001, 10005, 11000, 16000, 0, 4001, 17000])
    got = challenge_label_rgb(labels, "panoptic")
    assert got[:4].tolist() == np.rint(table[[4001, 4002, 7001, 10005]] * 255.0).astype(np.uint8).tolist()
    assert got[0].tolist() != got[1].tolist() and got[7].tolist() == got[0].tolist()
    assert got[4].tolist() == [0, 207, 191] and got[5].tolist() == [0, 175, 0] and got[6].tolist() == [0, 0, 0]
    assert got[8].tolist() not in got[:8].tolist()
    lidarseg = challenge_label_rgb(np.array([10, 11, 1]), "lidarseg")
    assert lidarseg.tolist() == [[255, 99, 71], [0, 207, 191], [112, 128, 144]]  # truck, driveable, barrier


def test_a_video_draws_the_predictions_not_the_ground_truth(labelled, submission, tmp_path):
    import cv2

    _, out = labelled
    common = ["render", str(out), "--scene", "scene-0001", "--frame-format", "png", "--quiet", "--lidar-color",
              "lidarseg"]
    assert main([*common, "--frames-dir", str(tmp_path / "truth")]) == 0
    assert main([*common, "--frames-dir", str(tmp_path / "pred"), "--lidar-predictions", str(submission)]) == 0
    assert main([*common, "--channel", "bev", "--frames-dir", str(tmp_path / "bev"), "--lidar-predictions",
                 str(submission)]) == 0
    orange_bgr = np.array([0, 158, 255])
    for folder in ("pred", "bev"):
        frames = sorted((tmp_path / folder).glob("*.png"))
        assert len(frames) == 3
        image = cv2.imread(str(frames[0]))
        assert (image == orange_bgr).all(axis=2).sum() > 20, folder  # every third point predicted car
    truth, pred = (cv2.imread(str(tmp_path / f / "00001.png")) for f in ("truth", "pred"))
    assert (truth != pred).any(axis=2).sum() > 20


def test_what_cannot_be_drawn_is_refused_naming_it(labelled, submission, tmp_path, capsys):
    import nuparquet

    root, out = labelled
    common = ["render", str(out), "--scene", "scene-0001", "--frames-dir", str(tmp_path / "f"), "--quiet"]
    assert main([*common, "--lidar-predictions", str(submission)]) == 2
    assert "give --lidar-color lidarseg or panoptic" in capsys.readouterr().err
    assert main([*common, "--lidar-color", "lidarseg", "--all-frames", "--lidar-predictions", str(submission)]) == 2
    assert "keyframe labels only" in capsys.readouterr().err
    lidar = _keyframe_lidar(out)
    ds = nuparquet.open(out)
    last = lidar["token"].to_list()[-1]
    moved = tmp_path / "partial"
    moved.mkdir()
    for path in (submission / "lidarseg" / "mini_val").iterdir():
        if not path.name.startswith(last):
            (moved / path.name).write_bytes(path.read_bytes())
    with pytest.raises(UsageError, match=f"no {last}_lidarseg.bin for lidar sample_data {last}"):
        CloudReader.build(lidar, root, dataset=ds, color="lidarseg", predictions=moved)
    (moved / f"{last}_lidarseg.bin").write_bytes(b"\x01\x02")
    reader = CloudReader.build(lidar, root, dataset=ds, color="lidarseg", predictions=moved)
    with pytest.raises(InputError, match=f"holds 2 predicted labels for the .* points of lidar sample_data {last}"):
        reader.cloud(lidar.height - 1)
    (moved / "sub").mkdir()
    (moved / "sub" / f"{last}_lidarseg.bin").write_bytes(b"\x01")
    with pytest.raises(UsageError, match="2 files .* not one"):
        CloudReader.build(lidar, root, dataset=ds, color="lidarseg", predictions=moved)
