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
