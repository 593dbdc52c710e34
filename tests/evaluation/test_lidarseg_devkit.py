"""The lidar segmentation evaluation against nuscenes-devkit's LidarSegEval itself, on the generated labelled set:
seeded perturbed predictions (classes the ground truth does not hold, ignored points predicted as anything),
perfect predictions (mIoU 1, checked on its own), a frame whose labels are all ignored; ground truth from
`lidar_points/` and from the label files. The result dicts are compared as JSON text: keys, their order and every
float exactly (the same numpy operations; NaN where the devkit has NaN)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from nuparquet.evaluation.segmentation.run import confusion_table
from tests.conftest import SYNTH_VERSION

pytestmark = pytest.mark.devkit

META = {"use_camera": False, "use_lidar": True, "use_radar": False, "use_map": False, "use_external": False}


@pytest.fixture(scope="module")
def devkit_nusc(labelled_root):
    from nuscenes import NuScenes

    return NuScenes(SYNTH_VERSION, dataroot=str(labelled_root), verbose=False)


def _train_scenes(nusc) -> list[str]:
    from nuscenes.utils.splits import create_splits_scenes

    present = {scene["name"] for scene in nusc.scene}
    return [name for name in create_splits_scenes()["train"] if name in present]


def devkit_lidarseg(nusc, results: Path, monkeypatch) -> dict:
    """LidarSegEval(nusc, results, "train").evaluate(), its split list cut to the scenes the small set holds."""
    from nuscenes.eval.lidarseg import utils
    from nuscenes.eval.lidarseg.evaluate import LidarSegEval

    names = _train_scenes(nusc)
    with monkeypatch.context() as patch:
        patch.setattr(utils, "create_splits_scenes", lambda verbose=False: {"train": names})
        return LidarSegEval(nusc, str(results), "train").evaluate()


def write_submission(nusc, folder: Path, seed: int | None, *, flip: float = 0.3) -> Path:
    """Predictions for every keyframe LIDAR_TOP of the train scenes: the ground truth mapped by the devkit's own
    mapper (ignored points predicted at random), then `flip` of the points replaced by a random class 1..16
    (seed None: none: perfect)."""
    from nuscenes.eval.lidarseg.utils import LidarsegClassMapper

    mapper = LidarsegClassMapper(nusc)
    rng = np.random.default_rng(seed if seed is not None else 0)
    (folder / "lidarseg" / "train").mkdir(parents=True)
    (folder / "train").mkdir()
    (folder / "train" / "submission.json").write_text(json.dumps({"meta": META}))
    for sample in nusc.sample:
        token = sample["data"]["LIDAR_TOP"]
        labels = np.fromfile(Path(nusc.dataroot) / nusc.get("lidarseg", token)["filename"], dtype=np.uint8)
        gt = mapper.convert_label(labels)
        pred = np.where(gt > 0, gt, rng.integers(1, 17, len(gt)))
        if seed is not None:
            flipped = rng.random(len(gt)) < flip
            pred[flipped] = rng.integers(1, 17, int(flipped.sum()))
        pred.astype(np.uint8).tofile(folder / "lidarseg" / "train" / f"{token}_lidarseg.bin")
    return folder


def as_json(metrics: dict) -> str:
    return json.dumps(metrics, indent=4)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_perturbed_predictions_equal_the_devkit(labelled_out, devkit_nusc, seed, tmp_path, monkeypatch):
    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    results = write_submission(devkit_nusc, tmp_path / "results", seed)
    theirs = devkit_lidarseg(devkit_nusc, results, monkeypatch)
    ours = evaluate_lidarseg(labelled_out, results, split="train")
    assert as_json(ours.metrics) == as_json(theirs)
    assert 0 < ours.metrics["miou"] < 1
    # the flips predict classes the ground truth does not hold: IoU 0 there, counted into the mean as the devkit does
    assert any(value == 0.0 for value in ours.metrics["iou_per_class"].values())
    assert ours.confusion[0].sum() == 0 and ours.confusion[:, 0].sum() == 0
    # counts of points, as the devkit's ConfusionMatrix holds them (integers, so confusion.parquet's are too)
    from nuscenes.eval.lidarseg.utils import ConfusionMatrix

    devkit_matrix = ConfusionMatrix(17, 0)
    devkit_matrix.update(np.array([1, 2]), np.array([1, 3]))
    assert ours.confusion.dtype == devkit_matrix.global_cm.dtype == np.int64
    assert confusion_table(ours.confusion).schema["points"] == pl.Int64


def test_perfect_predictions_score_one(labelled_out, devkit_nusc, tmp_path, monkeypatch):
    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    results = write_submission(devkit_nusc, tmp_path / "results", None)
    ours = evaluate_lidarseg(labelled_out, results, split="train")
    assert ours.metrics["miou"] == 1.0 and ours.metrics["freq_weighted_iou"] == 1.0
    assert as_json(ours.metrics) == as_json(devkit_lidarseg(devkit_nusc, results, monkeypatch))


@pytest.fixture(scope="module")
def ignored_root(labelled_root, tmp_path_factory) -> tuple[Path, Path, str]:
    """The labelled set with its first keyframe's labels all noise (ignored), converted without points: the
    ground truth then comes from the label files. (dataroot, OUT, the ignored frame's token)."""
    from nuparquet.conversion import convert

    root = tmp_path_factory.mktemp("lidarseg-ignored") / "data"
    root.mkdir()
    for name in ("samples", "sweeps", "maps", "panoptic"):
        (root / name).symlink_to(labelled_root / name)
    shutil.copytree(labelled_root / SYNTH_VERSION, root / SYNTH_VERSION)
    shutil.copytree(labelled_root / "lidarseg", root / "lidarseg")
    records = json.loads((root / SYNTH_VERSION / "lidarseg.json").read_text())
    noise = next(c["index"] for c in json.loads((root / SYNTH_VERSION / "category.json").read_text())
                 if c["name"] == "noise")
    first = root / records[0]["filename"]
    np.full(len(np.fromfile(first, dtype=np.uint8)), noise, dtype=np.uint8).tofile(first)
    out = tmp_path_factory.mktemp("lidarseg-ignored-out") / "out"
    convert(root, SYNTH_VERSION, out, workers=1)
    return root, out, records[0]["sample_data_token"]


def test_an_all_ignored_frame_and_labels_from_files_equal_the_devkit(ignored_root, tmp_path, monkeypatch):
    from nuscenes import NuScenes

    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    root, out, ignored = ignored_root
    nusc = NuScenes(SYNTH_VERSION, dataroot=str(root), verbose=False)
    results = write_submission(nusc, tmp_path / "results", 7)
    ours = evaluate_lidarseg(out, results, split="train")
    assert ignored in ours.frames
    assert as_json(ours.metrics) == as_json(devkit_lidarseg(nusc, results, monkeypatch))


@pytest.fixture()
def submission(devkit_nusc, tmp_path) -> Path:
    return write_submission(devkit_nusc, tmp_path / "results", 5)


def _first_file(results: Path) -> Path:
    return sorted((results / "lidarseg" / "train").iterdir())[0]


def test_a_missing_frame_names_its_token(labelled_out, submission):
    from nuparquet.errors import InputError
    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    path = _first_file(submission)
    path.unlink()
    token = path.name.removesuffix("_lidarseg.bin")
    with pytest.raises(InputError, match=f"no predictions for lidar sample_data {token}"):
        evaluate_lidarseg(labelled_out, submission, split="train")


def test_a_wrong_length_names_the_token_and_both_lengths(labelled_out, submission):
    from nuparquet.errors import InputError
    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    path = _first_file(submission)
    pred = np.fromfile(path, dtype=np.uint8)
    pred[:-1].tofile(path)
    token = path.name.removesuffix("_lidarseg.bin")
    with pytest.raises(InputError, match=f"{len(pred) - 1} predictions for lidar sample_data {token}, which has "
                       f"{len(pred)} points"):
        evaluate_lidarseg(labelled_out, submission, split="train")


@pytest.mark.parametrize("bad", [0, 17])
def test_a_class_out_of_range_is_refused(labelled_out, submission, bad):
    from nuparquet.errors import InputError
    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    path = _first_file(submission)
    pred = np.fromfile(path, dtype=np.uint8)
    pred[3] = bad
    pred.tofile(path)
    with pytest.raises(InputError, match=f"prediction {bad} at point 3 of lidar sample_data .* outside 1..16"):
        evaluate_lidarseg(labelled_out, submission, split="train")


def test_the_meta_is_checked_as_validate_submission_does(labelled_out, submission):
    from nuparquet.errors import InputError
    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    meta_path = submission / "train" / "submission.json"
    meta_path.write_text(json.dumps({"meta": {**META, "use_lidar": 1}}))
    with pytest.raises(InputError, match="meta.use_lidar must be true or false"):
        evaluate_lidarseg(labelled_out, submission, split="train")
    meta_path.unlink()
    with pytest.raises(InputError, match="submission.json .*does not exist"):
        evaluate_lidarseg(labelled_out, submission, split="train")


def test_the_one_verb_and_the_cli_write_the_devkit_dict(labelled_out, devkit_nusc, submission, tmp_path,
                                                         monkeypatch, capsys):
    import nuparquet
    from nuparquet.cli.main import main

    theirs = devkit_lidarseg(devkit_nusc, submission, monkeypatch)
    front = nuparquet.evaluate(labelled_out, submission, tmp_path / "front", task="lidarseg", split="train")
    assert as_json(front.metrics) == as_json(theirs)
    written = (tmp_path / "front" / "lidarseg_results.json").read_text()
    assert written == json.dumps(theirs, indent=4, sort_keys=False)
    assert main(["eval", str(labelled_out), "--task", "lidarseg", "--results", str(submission), "--split", "train",
                 "--out", str(tmp_path / "cli"), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert (tmp_path / "cli" / "lidarseg_results.json").read_text() == written
    assert f"mIoU: {theirs['miou']:.4f}" in printed and "driveable_surface" in printed


def test_settings_of_other_tasks_a_file_and_an_empty_split_are_refused(labelled_out, submission):
    from nuparquet.errors import InputError, UsageError
    from nuparquet.evaluation.segmentation import evaluate_lidarseg

    with pytest.raises(UsageError, match="--config and --config-file do not apply to --task lidarseg"):
        evaluate_lidarseg(labelled_out, submission, split="train", config="detection_cvpr_2019")
    with pytest.raises(UsageError, match="--by visibility: --task lidarseg slices by distance, location, night"):
        evaluate_lidarseg(labelled_out, submission, split="train", by=("visibility",))
    with pytest.raises(UsageError, match="a lidarseg submission is a folder"):
        evaluate_lidarseg(labelled_out, submission / "train" / "submission.json", split="train")
    (submission / "mini_val").mkdir()
    (submission / "mini_val" / "submission.json").write_text(json.dumps({"meta": META}))
    (submission / "lidarseg" / "mini_val").mkdir()
    with pytest.raises(InputError, match="split mini_val: the dataset holds no keyframe LIDAR_TOP reading"):
        evaluate_lidarseg(labelled_out, submission, split="mini_val")


class _Categories:
    """A dataset stand-in holding only a category table."""

    root = "OUT"

    def __init__(self, rows: dict):
        import polars as pl

        self.table = pl.LazyFrame(rows)

    def scan(self, name: str):
        assert name == "tables/category"
        return self.table


def test_the_class_lookup_is_the_devkit_mappers_and_refuses_what_it_cannot_map():
    from nuscenes.eval.lidarseg.utils import LidarsegClassMapper

    from nuparquet.errors import InputError
    from nuparquet.evaluation.segmentation.classes import fine_to_coarse_lookup

    from nuparquet.evaluation.segmentation.classes import FINE_TO_COARSE

    names = list(FINE_TO_COARSE)
    order = np.random.default_rng(4).permutation(len(names))  # indices in another order than the names
    nusc = type("Stub", (), {"lidarseg_name2idx_mapping": {names[i]: j for j, i in enumerate(order.tolist())}})
    expected = LidarsegClassMapper(nusc).fine_idx_2_coarse_idx_mapping
    lookup = fine_to_coarse_lookup(_Categories({"name": [names[i] for i in order], "index": list(range(len(names)))}))
    assert lookup.tolist() == [expected[i] for i in range(len(names))]
    with pytest.raises(InputError, match="category 'vehicle.spaceship' has a lidarseg index"):
        fine_to_coarse_lookup(_Categories({"name": ["vehicle.car", "vehicle.spaceship"], "index": [0, 1]}))
    with pytest.raises(InputError, match="no `index` column"):
        fine_to_coarse_lookup(_Categories({"name": ["vehicle.car"]}))


def test_a_label_that_is_no_categorys_index_names_the_frame(labelled_out, submission, monkeypatch):
    from nuparquet.errors import InputError
    from nuparquet.evaluation.segmentation import classes, evaluate_lidarseg, run

    lookup = classes.fine_to_coarse_lookup(__import__("nuparquet").open(labelled_out))
    lookup[:] = -1  # as if no category held any of the indices the labels use
    monkeypatch.setattr(run, "fine_to_coarse_lookup", lambda dataset: lookup)
    with pytest.raises(InputError, match="lidarseg label .* at point 0 of lidar sample_data .* is the index of no "
                       "category"):
        evaluate_lidarseg(labelled_out, submission, split="train")
    monkeypatch.setattr(run, "fine_to_coarse_lookup", lambda dataset: lookup[:0])
    with pytest.raises(InputError, match="is the index of no category"):
        evaluate_lidarseg(labelled_out, submission, split="train")
