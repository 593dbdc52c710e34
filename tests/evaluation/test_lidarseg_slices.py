"""The lidarseg evaluation per slice: a scene's slice equals the devkit's LidarSegEval run on that scene alone, a
distance bin's equals the devkit's ConfusionMatrix fed only the points of the bin (read from the files here), the
bins are half-open and cover every point, and the slices and plots are written beside the result."""

from __future__ import annotations

import json

import numpy as np
import polars as pl
import pytest

from nuparquet.evaluation.segmentation.classes import COARSE_NAMES
from nuparquet.evaluation.segmentation.slicing import SliceConfusions
from tests.conftest import SYNTH_VERSION
from tests.evaluation.test_lidarseg_devkit import _train_scenes, as_json, write_submission

pytestmark = pytest.mark.devkit


@pytest.fixture(scope="module")
def devkit_nusc(labelled_root):
    from nuscenes import NuScenes

    return NuScenes(SYNTH_VERSION, dataroot=str(labelled_root), verbose=False)


@pytest.fixture(scope="module")
def sliced(labelled_out, devkit_nusc, tmp_path_factory):
    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    results = write_submission(devkit_nusc, tmp_path_factory.mktemp("lidarseg-slices") / "results", 5)
    out = tmp_path_factory.mktemp("lidarseg-slices-out") / "eval"
    return results, evaluate_lidarseg(labelled_out, results, out, split="train", by=("scene", "distance"),
                                      bins=("0", "10", "20"))


def test_a_scene_slice_is_the_devkit_on_that_scene_alone(sliced, devkit_nusc, monkeypatch):
    from nuscenes.eval.lidarseg import utils
    from nuscenes.eval.lidarseg.evaluate import LidarSegEval

    results, ours = sliced
    scenes = _train_scenes(devkit_nusc)
    assert len(scenes) >= 2
    assert [label for by, label in ours.slice_summaries if by == "scene"] == sorted(scenes)
    for name in scenes:
        with monkeypatch.context() as patch:
            patch.setattr(utils, "create_splits_scenes", lambda verbose=False, name=name: {"train": [name]})
            theirs = LidarSegEval(devkit_nusc, str(results), "train").evaluate()
        assert as_json(ours.slice_summaries[("scene", name)]) == as_json(theirs), name
        scene = next(s for s in devkit_nusc.scene if s["name"] == name)
        row = ours.slices.filter((pl.col("by") == "scene") & (pl.col("slice") == name)).row(0, named=True)
        assert row["frames"] == scene["nbr_samples"] and row["miou"] == theirs["miou"]


def test_a_distance_bin_is_the_devkit_matrix_of_the_points_in_it(sliced, devkit_nusc, labelled_root):
    from nuscenes.eval.lidarseg.utils import ConfusionMatrix, LidarsegClassMapper

    results, ours = sliced
    mapper = LidarsegClassMapper(devkit_nusc)
    bins = {"0-10m": (0.0, 10.0), "10-20m": (10.0, 20.0), "20m+": (20.0, np.inf)}
    matrices = {label: ConfusionMatrix(17, 0) for label in bins}
    names = set(_train_scenes(devkit_nusc))
    for sample in devkit_nusc.sample:
        if devkit_nusc.get("scene", sample["scene_token"])["name"] not in names:
            continue
        token = sample["data"]["LIDAR_TOP"]
        xy = np.fromfile(labelled_root / devkit_nusc.get("sample_data", token)["filename"],
                         dtype=np.float32).reshape(-1, 5)[:, :2]
        gt = mapper.convert_label(np.fromfile(labelled_root / devkit_nusc.get("lidarseg", token)["filename"],
                                              dtype=np.uint8))
        pred = np.fromfile(results / "lidarseg" / "train" / f"{token}_lidarseg.bin", dtype=np.uint8)
        distance = np.hypot(xy[:, 0], xy[:, 1])
        for label, (low, high) in bins.items():
            inside = (distance >= low) & (distance < high)
            matrices[label].update(gt[inside], pred[inside])
    labels = [label for by, label in ours.slice_summaries if by == "distance"]
    assert labels == [label for label in bins if matrices[label].global_cm.sum() > 0] and len(labels) >= 2
    total = np.zeros((17, 17), np.int64)
    for label in labels:
        theirs = matrices[label]
        assert np.array_equal(ours.slice_confusions[("distance", label)], theirs.global_cm), label
        metrics = ours.slice_summaries[("distance", label)]
        iou = theirs.get_per_class_iou()
        assert list(metrics["iou_per_class"]) == list(COARSE_NAMES)
        assert np.array_equal(np.array(list(metrics["iou_per_class"].values())), iou, equal_nan=True)
        assert metrics["miou"] == theirs.get_mean_iou() and metrics["freq_weighted_iou"] == theirs.get_freqweighted_iou()
        total += theirs.global_cm
    assert np.array_equal(total, ours.confusion)  # every scored point is in exactly one bin


def test_the_bins_are_half_open_and_the_last_is_open_ended():
    frames = pl.DataFrame({"name": ["s"], "description": [""], "log_location": ["x"]})
    slices = SliceConfusions(["distance"], frames, (0.0, 10.0, 50.0))
    # 6-8-10 and 30-40-50 triangles: exactly on an edge, in float32 as the points are
    xy = np.array([[6, 8], [9.999, 0], [30, 40], [0, 49.9], [0, 0]], np.float32)
    gt = np.array([1, 2, 3, 4, 5])
    slices.add(0, xy, gt, gt, np.zeros((17, 17), np.int64))
    found = {label: np.flatnonzero(np.diagonal(slices.confusion[("distance", label)])).tolist()
             for label in ("0-10m", "10-50m", "50m+")}
    assert found == {"0-10m": [2, 5], "10-50m": [1, 4], "50m+": [3]}
    assert list(slices.summaries()) == [("distance", "0-10m"), ("distance", "10-50m"), ("distance", "50m+")]


def test_slices_and_plots_are_written_beside_the_result(labelled_out, devkit_nusc, tmp_path):
    import cv2

    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    results = write_submission(devkit_nusc, tmp_path / "results", 6)
    ours = evaluate_lidarseg(labelled_out, results, tmp_path / "eval", split="train", by=("scene", "distance"))
    written = pl.read_parquet(ours.out / "slices.parquet")
    assert written.equals(ours.slices)
    assert written.columns[:6] == ["by", "slice", "frames", "points", "miou", "freq_weighted_iou"]
    for (by, label), metrics in ours.slice_summaries.items():
        folder = ours.out / "slices" / by / label
        assert json.loads((folder / "lidarseg_results.json").read_text()) == json.loads(json.dumps(metrics))
        points = pl.read_parquet(folder / "confusion.parquet")["points"].to_numpy()
        assert np.array_equal(points, ours.slice_confusions[(by, label)].ravel())
    for name in ("iou_per_class.png", "confusion.png"):
        image = cv2.imread(str(ours.out / "plots" / name))
        assert image is not None and image.std() > 10, name


def test_the_iou_plot_draws_each_class_as_a_bar_of_its_iou_and_names_it():
    import matplotlib.pyplot as plt

    from nuparquet.evaluation.segmentation.plots import iou_figure

    iou = {name: (i % 5) / 5 for i, name in enumerate(COARSE_NAMES)}
    iou["bus"] = float("nan")  # neither in the ground truth nor predicted: no bar
    fig = iou_figure({"iou_per_class": iou, "miou": 0.4, "freq_weighted_iou": 0.5})
    ax = fig.axes[0]
    heights = [bar.get_height() for bar in ax.patches]
    assert heights == [0.0 if name == "bus" else iou[name] for name in COARSE_NAMES[1:]]
    labels = ax.get_xticklabels()
    assert [t.get_text() for t in labels] == list(COARSE_NAMES[1:]) and labels[0].get_rotation() == 60
    assert ax.get_lines()[0].get_ydata()[0] == 0.4 and "mIoU 0.400" in ax.get_legend().get_texts()[0].get_text()
    plt.close(fig)


def test_the_confusion_plot_shows_each_ground_truth_row_as_fractions():
    from nuparquet.evaluation.segmentation.plots import row_fractions

    confusion = np.zeros((17, 17), np.int64)
    confusion[1, 1], confusion[1, 2], confusion[3, 3] = 3, 1, 5
    confusion[0, 4] = 7  # the ignore row is left out
    fractions = row_fractions(confusion)
    assert fractions.shape == (16, 16)
    assert fractions[0, 0] == 0.75 and fractions[0, 1] == 0.25 and fractions[2, 2] == 1.0
    assert np.isnan(fractions[1]).all() and np.isnan(fractions[3]).all()


def test_a_split_the_dataset_holds_in_part_says_so_and_a_whole_one_does_not(labelled_out, devkit_nusc, tmp_path):
    """Scenes of the split that the dataset lacks are left out with a note naming the counts; a (custom) split whose
    every scene is there evaluates without one."""
    import nuparquet
    from nuparquet.evaluation.segmentation import evaluate_lidarseg
    from nuscenes.utils.splits import create_splits_scenes

    results = write_submission(devkit_nusc, tmp_path / "results", 2)
    present = {scene["name"] for scene in devkit_nusc.scene}
    train = [name for name in create_splits_scenes()["train"] if name in present]
    partial = evaluate_lidarseg(labelled_out, results, split="train")
    assert partial.notes == [f"the dataset holds {len(train)} of the {len(create_splits_scenes()['train'])} scenes of "
                             "split train: evaluated on those"]
    root = tmp_path / "root"
    (root / SYNTH_VERSION).mkdir(parents=True)
    (root / SYNTH_VERSION / "splits.json").write_text(json.dumps({"mine": train}))  # ground truth: lidar_points/
    (results / "mine").mkdir()
    (results / "mine" / "submission.json").write_text((results / "train" / "submission.json").read_text())
    (results / "lidarseg" / "mine").symlink_to(results / "lidarseg" / "train")
    whole = evaluate_lidarseg(nuparquet.open(labelled_out, dataroot=root), results, split="mine")
    assert whole.notes == [] and json.dumps(whole.metrics) == json.dumps(partial.metrics)  # NaN where absent


def test_the_confusion_plot_names_the_classes_on_both_axes_alike():
    """Columns (predicted, names turned upright) and rows (ground truth) name the 16 challenge classes in the
    same order and the same small type, so that each name sits in line with its cell."""
    import matplotlib.pyplot as plt

    from nuparquet.evaluation.segmentation.plots import confusion_figure

    fig = confusion_figure(np.eye(17, dtype=np.int64))
    ax = fig.axes[0]
    x, y = ax.get_xticklabels(), ax.get_yticklabels()
    assert [t.get_text() for t in x] == [t.get_text() for t in y] == list(COARSE_NAMES[1:])
    assert x[0].get_rotation() == 90 and y[0].get_rotation() == 0
    assert {t.get_fontsize() for t in x} == {t.get_fontsize() for t in y} == {7.0}
    plt.close(fig)
