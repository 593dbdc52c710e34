"""The panoptic evaluations per slice: a scene's slice is the devkit's NuScenesPanopticEval run on that scene alone
(segmentation and tracking), a slice of several scenes is the devkit's on those scenes, and the slices are written
beside the result."""

from __future__ import annotations

import json

import panoptic_submissions as make  # tests/evaluation/, on sys.path under pytest
import polars as pl
import pytest

from tests.conftest import SYNTH_VERSION
from tests.evaluation.test_panoptic_devkit import assert_equal_to_devkit

pytestmark = pytest.mark.devkit


@pytest.fixture(scope="module")
def devkit_nusc(labelled_root):
    from nuscenes import NuScenes

    return NuScenes(SYNTH_VERSION, dataroot=str(labelled_root), verbose=False)


def devkit_on(nusc, results, task: str, names: list[str], out, monkeypatch) -> str:
    """NuScenesPanopticEval on the scenes `names` only (its split list replaced): the written file's text."""
    from nuscenes.eval.lidarseg import utils
    from nuscenes.eval.panoptic import evaluate

    with monkeypatch.context() as patch:
        for module in (utils, evaluate):
            patch.setattr(module, "create_splits_scenes", lambda verbose=False: {"train": names})
        evaluate.NuScenesPanopticEval(nusc, str(results), "train", task, 15, out_dir=str(out)).evaluate()
    return (out / f"{task}-result.json").read_text()


def test_each_scene_slice_and_a_location_slice_are_the_devkit_on_their_scenes(labelled_out, devkit_nusc, tmp_path,
                                                                            monkeypatch):
    from nuparquet.evaluation.panoptic import evaluate_panoptic
    from nuscenes.utils.splits import create_splits_scenes

    results = make.write(devkit_nusc, tmp_path / "results", 7)
    present = {scene["name"] for scene in devkit_nusc.scene}
    train = [name for name in create_splits_scenes()["train"] if name in present]
    assert len(train) >= 2
    ours = evaluate_panoptic(labelled_out, results, tmp_path / "eval", task="panoptic-tracking", split="train",
                             by=("scene", "location"))
    assert [label for by, label in ours.slice_summaries if by == "scene"] == sorted(train)
    for name in train:
        theirs = devkit_on(devkit_nusc, results, "tracking", [name], tmp_path / f"devkit-{name}", monkeypatch)
        assert_equal_to_devkit(ours.slice_summaries[("scene", name)], theirs)  # its file holds both tasks
        written = json.loads((tmp_path / "eval" / "slices" / "scene" / name / "tracking-result.json").read_text())
        assert written == json.loads(json.dumps(ours.slice_summaries[("scene", name)]))
    location_of = {s["name"]: devkit_nusc.get("log", s["log_token"])["location"] for s in devkit_nusc.scene}
    for (by, label), metrics in ours.slice_summaries.items():
        if by != "location":
            continue
        names = [name for name in train if location_of[name] == label]
        theirs = devkit_on(devkit_nusc, results, "segmentation", names, tmp_path / f"devkit-loc-{label}", monkeypatch)
        assert_equal_to_devkit({"segmentation": metrics["segmentation"]}, theirs)
    table = pl.read_parquet(tmp_path / "eval" / "slices.parquet")
    assert table.equals(ours.slices) and set(table["by"]) == {"scene", "location"}
    first = table.filter((pl.col("by") == "scene") & (pl.col("slice") == train[0])).row(0, named=True)
    scene = next(s for s in devkit_nusc.scene if s["name"] == train[0])
    assert first["frames"] == scene["nbr_samples"]
    assert first["PAT"] == ours.slice_summaries[("scene", train[0])]["tracking"]["all"]["PAT"]


def bar_heights(fig) -> list[float]:
    """The heights of the figure's bars, in the order drawn (each series over every class, then the next)."""
    return [bar.get_height() for bar in fig.axes[0].patches]


def test_the_plots_are_written_and_their_bars_are_the_result_json(labelled_out, devkit_nusc, tmp_path):
    import cv2
    import matplotlib.pyplot as plt
    import numpy as np

    from nuparquet.evaluation.panoptic import evaluate_panoptic
    from nuparquet.evaluation.panoptic.plots import CLASSES, pq_figure, ptq_figure
    from nuparquet.evaluation.segmentation.classes import COARSE_NAMES

    results = make.write(devkit_nusc, tmp_path / "results", 7)
    ours = evaluate_panoptic(labelled_out, results, tmp_path / "eval", task="panoptic-tracking", split="train")
    for name in ("pq_per_class.png", "ptq_per_class.png"):
        image = cv2.imread(str(ours.out / "plots" / name))
        assert image is not None and image.std() > 10, name
    written = json.loads((ours.out / "tracking-result.json").read_text())
    assert CLASSES == COARSE_NAMES[1:]
    for figure, part, keys in ((pq_figure, "segmentation", ("PQ", "SQ", "RQ")),
                               (ptq_figure, "tracking", ("PTQ", "sPTQ"))):
        fig = figure(written[part])
        expected = [written[part][c][k] for k in keys for c in COARSE_NAMES[1:]]
        assert np.allclose(bar_heights(fig), np.nan_to_num(expected), rtol=0, atol=0)
        assert [t.get_text() for t in fig.axes[0].get_xticklabels()] == list(COARSE_NAMES[1:])
        assert fig.axes[0].get_lines()[0].get_ydata()[0] == written[part]["all"][keys[0]]
        plt.close(fig)
    assert not (tmp_path / "bare").exists()
    evaluate_panoptic(labelled_out, results, tmp_path / "bare", task="panoptic-tracking", split="train", plots=False)
    assert not (tmp_path / "bare" / "plots").exists()


def test_a_slice_whose_scenes_hold_no_thing_instance_gets_a_note_instead_of_tracking_figures():
    import numpy as np

    from nuparquet.errors import InputError
    from nuparquet.evaluation.panoptic.quality import MIN_STUFF_INDEX, PanopticQuality
    from nuparquet.evaluation.panoptic.segments import frame_segments
    from nuparquet.evaluation.panoptic.slicing import TRACKING_COLUMNS, SliceEvaluations
    from nuparquet.evaluation.panoptic.tracking import PanopticTracking
    from nuparquet.evaluation.segmentation.classes import NUM_CLASSES

    identity = np.arange(NUM_CLASSES)  # fine category index = coarse class here
    stuff = MIN_STUFF_INDEX * 1000
    car = np.r_[np.full(20, 1000 + 1), np.full(30, stuff)]  # a thing instance of 20 points (> 15), and stuff
    only_stuff = np.r_[np.full(30, stuff), np.full(20, (MIN_STUFF_INDEX + 1) * 1000)]
    frames = [("a", frame_segments(car, car, identity)), ("a", frame_segments(car, car, identity)),
              ("b", frame_segments(only_stuff, only_stuff, identity))]
    slices = SliceEvaluations(["scene"], pl.DataFrame({"name": [s for s, _ in frames]}), None, 15, True)
    for frame, (scene, seg) in enumerate(frames):
        slices.add(frame, scene, seg)
    summaries, notes = slices.summaries()
    assert list(summaries) == [("scene", "a"), ("scene", "b")]
    assert "tracking" in summaries[("scene", "a")] and "tracking" not in summaries[("scene", "b")]
    alone = PanopticTracking(15)
    alone.add("b", frames[2][1])
    with pytest.raises(InputError) as raised:
        alone.metrics()
    assert notes == [f"slice scene b: no tracking figures ({raised.value})"]
    quality = PanopticQuality(15)
    quality.add(frames[2][1])
    assert json.dumps(summaries[("scene", "b")]["segmentation"]) == json.dumps(quality.metrics())
    table = slices.table(summaries)
    row_b = table.filter(pl.col("slice") == "b")
    assert row_b["frames"].to_list() == [1] and all(row_b[c].is_null().all() for c in TRACKING_COLUMNS)
    assert not table.filter(pl.col("slice") == "a")[list(TRACKING_COLUMNS)].null_count().sum_horizontal().item()
