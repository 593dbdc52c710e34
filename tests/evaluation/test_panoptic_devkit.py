"""The panoptic segmentation and panoptic tracking evaluation against nuscenes-devkit's NuScenesPanopticEval
itself, on the generated labelled set (Panoptic nuScenes ground truth: category index * 1000 + instance id, ids
stable along a track): seeded perturbed submissions (instances split, merged, labelled as stuff and stuff as
things, identities switched between frames, fragments of classes absent from the ground truth, instances under
min_inst_points), the perfect submission, a frame whose ground truth is all ignored; ground truth from
`lidar_points/` and from the label files. The written result files are compared as JSON text, every float
exactly, except PQ-dagger / PTQ-dagger, whose last bits the devkit's set order decides (docs/CONTRACTS.md)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import panoptic_submissions as make  # tests/evaluation/, on sys.path under pytest
import pytest

from tests.conftest import SYNTH_VERSION

pytestmark = pytest.mark.devkit

DAGGERS = {"segmentation": "PQ_dagger", "tracking": "PTQ_dagger"}


@pytest.fixture(scope="module")
def devkit_nusc(labelled_root):
    from nuscenes import NuScenes

    return NuScenes(SYNTH_VERSION, dataroot=str(labelled_root), verbose=False)


def devkit_panoptic(nusc, results: Path, task: str, min_points: int, out: Path, monkeypatch):
    """NuScenesPanopticEval(nusc, results, "train", task, min_points).evaluate(), its split list cut to the scenes
    the small set holds: (the written file's text, the evaluator)."""
    from nuscenes.eval.lidarseg import utils
    from nuscenes.eval.panoptic import evaluate
    from nuscenes.utils.splits import create_splits_scenes

    present = {scene["name"] for scene in nusc.scene}
    names = [name for name in create_splits_scenes()["train"] if name in present]
    with monkeypatch.context() as patch:
        for module in (utils, evaluate):
            patch.setattr(module, "create_splits_scenes", lambda verbose=False: {"train": names})
        evaluator = evaluate.NuScenesPanopticEval(nusc, str(results), "train", task, min_points, out_dir=str(out))
        evaluator.evaluate()
    return (out / f"{task}-result.json").read_text(), evaluator


def assert_equal_to_devkit(ours: dict, theirs_text: str) -> None:
    """Every value exactly, the daggers within 1e-12 relative, and the daggers exactly the mean, in class index
    order, of the devkit's own per-class values."""
    theirs = json.loads(theirs_text)
    assert list(ours) == list(theirs)
    mine = json.loads(json.dumps(ours))
    for task, key in DAGGERS.items():
        if task not in theirs:
            continue
        per_class = theirs[task]
        term = key.removesuffix("_dagger")
        expected = np.mean([per_class[n][term] for n in make_names()[1:11]] +
                           [per_class[n]["IoU"] for n in make_names()[11:]])
        assert mine[task]["all"][key] == expected
        assert mine[task]["all"][key] == pytest.approx(per_class["all"][key], rel=1e-12, abs=0)
        mine[task]["all"][key] = per_class["all"][key]
    assert json.dumps(mine, indent=2) == theirs_text


def make_names() -> tuple[str, ...]:
    from nuparquet.evaluation.segmentation.classes import COARSE_NAMES

    return COARSE_NAMES


def _counts_equal(result, evaluator) -> None:
    seg = evaluator.evaluator["segmentation"]
    classes = result.classes
    assert classes["tp"].to_list() == seg.pan_tp.tolist()
    assert classes["fp"].to_list() == seg.pan_fp.tolist()
    assert classes["fn"].to_list() == seg.pan_fn.tolist()
    assert classes["iou_sum"].to_list() == seg.pan_iou.tolist()
    if "tracking" in evaluator.evaluator:
        track = evaluator.evaluator["tracking"]
        assert classes["tracking_tp"].to_list() == track.pan_tp.tolist()
        assert classes["tracking_iou_sum"].to_list() == track.pan_iou.tolist()
        assert classes["switches"].to_list() == track.pan_ids.tolist()
        assert classes["soft_switches"].to_list() == track.pan_soft_ids.tolist()


@pytest.mark.parametrize(("seed", "task", "min_points", "dtype"), [
    (1, "segmentation", 15, np.uint16), (2, "tracking", 15, np.int32), (3, "tracking", 40, np.uint16),
    (4, "tracking", 0, np.int64)])
def test_perturbed_submissions_equal_the_devkit(labelled_out, devkit_nusc, seed, task, min_points, dtype,
                                                tmp_path, monkeypatch):
    from nuparquet.evaluation.panoptic import evaluate_panoptic

    results = make.write(devkit_nusc, tmp_path / "results", seed, dtype=dtype)
    theirs, evaluator = devkit_panoptic(devkit_nusc, results, task, min_points, tmp_path / "devkit", monkeypatch)
    ours = evaluate_panoptic(labelled_out, results, tmp_path / "ours", split="train", min_inst_points=min_points,
                             task="panoptic" if task == "segmentation" else "panoptic-tracking")
    assert_equal_to_devkit(ours.metrics, theirs)
    _counts_equal(ours, evaluator)
    text = (tmp_path / "ours" / f"{task}-result.json").read_text()
    written = json.loads(text)
    assert written == json.loads(json.dumps(ours.metrics))
    assert text == json.dumps(written, indent=2)  # laid out as the devkit's save_result: json.dump(indent=2)
    # the perturbations reach the edges: misses and false instances, instances under the minimum counted nowhere
    classes = ours.classes
    assert classes["fn"].sum() > 0 and classes["fp"].sum() > 0 and classes["tp"].sum() > 0
    seg = ours.metrics["segmentation"]
    assert 0 < seg["all"]["PQ"] < 1
    instances = ours.instances
    if min_points > 0:
        assert instances.filter(instances["term"].is_null() & (instances["points"] < min_points)).height > 0
    # classes the ground truth does not hold, predicted: RQ 0 (FPs, no TP), PQ 0, counted into the means
    absent = classes.filter((classes["tp"] == 0) & (classes["fn"] == 0) & (classes["fp"] > 0))
    assert absent.height > 0 or min_points == 40
    # the instance table's terms are the counts
    for term, column in (("TP", "tp"), ("FN", "fn")):
        per_class = instances.filter((instances["side"] == "gt") & (instances["term"] == term))["class_index"]
        assert np.bincount(per_class.to_numpy(), minlength=17).tolist() == classes[column].to_list()
    fps = instances.filter((instances["side"] == "pred") & (instances["term"] == "FP"))["class_index"]
    assert np.bincount(fps.to_numpy(), minlength=17).tolist() == classes["fp"].to_list()
    if task == "tracking":
        assert classes["switches"].sum() > 0
        assert np.isfinite(ours.metrics["tracking"]["all"]["PAT"])


def test_the_perfect_submission_scores_one(labelled_out, devkit_nusc, tmp_path, monkeypatch):
    from nuparquet.evaluation.panoptic import evaluate_panoptic

    results = make.write(devkit_nusc, tmp_path / "results", None)
    theirs, _ = devkit_panoptic(devkit_nusc, results, "tracking", 15, tmp_path / "devkit", monkeypatch)
    ours = evaluate_panoptic(labelled_out, results, split="train", task="panoptic-tracking")
    assert_equal_to_devkit(ours.metrics, theirs)
    present = ours.classes.filter(ours.classes["tp"] > 0)["class"].to_list()
    for name in present:
        assert ours.metrics["segmentation"][name]["PQ"] == 1.0
    assert ours.metrics["tracking"]["all"]["TQ"] == 1.0
    assert ours.classes["switches"].sum() == 0 and ours.classes["fp"].sum() == 0 and ours.classes["fn"].sum() == 0


def test_ground_truth_ids_are_stable_along_tracks(devkit_nusc):
    """The generator's panoptic labels: one instance id per annotation instance across a scene's frames, its
    category index the annotation's."""
    by_label: dict[tuple[str, int], set] = {}
    for sample in devkit_nusc.sample:
        token = sample["data"]["LIDAR_TOP"]
        raw, _ = make.ground_truth(devkit_nusc, token)
        scene = sample["scene_token"]
        categories = {}
        for ann_token in sample["anns"]:
            ann = devkit_nusc.get("sample_annotation", ann_token)
            categories.setdefault(ann["instance_token"], devkit_nusc.get("category", devkit_nusc.get(
                "instance", ann["instance_token"])["category_token"])["index"])
        for label in np.unique(raw[raw % 1000 > 0]).tolist():
            by_label.setdefault((scene, label % 1000), set()).add(label // 1000)
        assert all(label // 1000 in categories.values() for label in np.unique(raw[raw % 1000 > 0]).tolist())
    assert by_label and all(len(cats) == 1 for cats in by_label.values())  # an id keeps its category in a scene
    assert any(sum(1 for s in devkit_nusc.sample if s["scene_token"] == scene) > 1 for scene, _ in by_label)


@pytest.fixture(scope="module")
def ignored_root(labelled_root, tmp_path_factory) -> tuple[Path, Path, str]:
    """The labelled set with its first keyframe's panoptic labels all noise (ignored), converted without points:
    the ground truth then comes from the label files. (dataroot, OUT, the ignored frame's token)."""
    from nuparquet.conversion import convert

    root = tmp_path_factory.mktemp("panoptic-ignored") / "data"
    root.mkdir()
    for name in ("samples", "sweeps", "maps", "lidarseg"):
        (root / name).symlink_to(labelled_root / name)
    shutil.copytree(labelled_root / SYNTH_VERSION, root / SYNTH_VERSION)
    shutil.copytree(labelled_root / "panoptic", root / "panoptic")
    records = json.loads((root / SYNTH_VERSION / "panoptic.json").read_text())
    first = root / records[0]["filename"]
    np.savez_compressed(first, data=np.zeros(len(np.load(first)["data"]), dtype=np.uint16))
    out = tmp_path_factory.mktemp("panoptic-ignored-out") / "out"
    convert(root, SYNTH_VERSION, out, workers=1)
    return root, out, records[0]["sample_data_token"]


def test_an_all_ignored_frame_and_labels_from_files_equal_the_devkit(ignored_root, tmp_path, monkeypatch):
    from nuscenes import NuScenes

    from nuparquet.evaluation.panoptic import evaluate_panoptic

    root, out, ignored = ignored_root
    nusc = NuScenes(SYNTH_VERSION, dataroot=str(root), verbose=False)
    results = make.write(nusc, tmp_path / "results", 7)
    theirs, _ = devkit_panoptic(nusc, results, "tracking", 15, tmp_path / "devkit", monkeypatch)
    ours = evaluate_panoptic(out, results, split="train", task="panoptic-tracking")
    assert ignored in ours.frames
    import polars as pl

    # its points are all dropped before instances are formed, predictions too (the devkit's filter by ground truth)
    assert ours.instances.filter(pl.col("sample_data_token") == ignored).is_empty()
    assert ours.instances["sample_data_token"].n_unique() == len(ours.frames) - 1
    assert_equal_to_devkit(ours.metrics, theirs)


@pytest.fixture()
def submission(devkit_nusc, tmp_path) -> Path:
    return make.write(devkit_nusc, tmp_path / "results", 5)


def _first_file(results: Path) -> tuple[Path, str]:
    path = min((results / "panoptic" / "train").iterdir())
    return path, path.name.removesuffix("_panoptic.npz")


def _evaluate(out, results, **fields):
    from nuparquet.evaluation.panoptic import evaluate_panoptic

    return evaluate_panoptic(out, results, split="train", **fields)


def test_a_missing_frame_names_its_file_and_token(labelled_out, submission):
    from nuparquet.errors import InputError

    path, token = _first_file(submission)
    path.unlink()
    with pytest.raises(InputError, match=f"{path}.*no predictions for lidar sample_data {token}"):
        _evaluate(labelled_out, submission)
    shutil.rmtree(submission / "panoptic" / "train")
    with pytest.raises(InputError, match="panoptic/train does not exist"):
        _evaluate(labelled_out, submission)


def test_a_wrong_length_names_the_token_and_both_counts(labelled_out, submission):
    from nuparquet.errors import InputError

    path, token = _first_file(submission)
    pred = np.load(path)["data"]
    np.savez_compressed(path, data=np.append(pred, pred[:1]))
    with pytest.raises(InputError, match=f"{len(pred) + 1} predictions for lidar sample_data {token}, which has "
                       f"{len(pred)} points"):
        _evaluate(labelled_out, submission)


@pytest.mark.parametrize(("bad", "dtype"), [(17000, np.uint16), (16999 + 1, np.int32), (-1, np.int32)])
def test_a_label_whose_class_is_out_of_range_is_refused(labelled_out, submission, bad, dtype):
    from nuparquet.errors import InputError

    path, token = _first_file(submission)
    pred = np.load(path)["data"].astype(dtype)
    pred[3] = bad
    np.savez_compressed(path, data=pred)
    with pytest.raises(InputError, match=f"label {bad} at point 3 of lidar sample_data {token} has a class outside "
                       "0..16"):
        _evaluate(labelled_out, submission)
    pred[3] = 16999  # the largest label of the last class is taken
    np.savez_compressed(path, data=pred)
    _evaluate(labelled_out, submission)


@pytest.mark.parametrize("content", ["no data", "floats", "two dims", "not a zip"])
def test_an_unreadable_prediction_file_names_it(labelled_out, submission, content):
    from nuparquet.errors import InputError

    path, token = _first_file(submission)
    pred = np.load(path)["data"]
    if content == "no data":
        np.savez_compressed(path, labels=pred)
        message = "no 'data' array \\(it holds labels\\)"
    elif content == "floats":
        np.savez_compressed(path, data=pred.astype(np.float32))
        message = "'data' is float32 of shape"
    elif content == "two dims":
        np.savez_compressed(path, data=pred.reshape(1, -1))
        message = "'data' is uint16 of shape \\(1, "
    else:
        path.write_bytes(b"not a zip")
        message = "not a readable .npz file"
    with pytest.raises(InputError, match=f"{message}.*{token}|{token}.*{message}"):
        _evaluate(labelled_out, submission)


def test_the_submission_json_is_checked(labelled_out, submission):
    from nuparquet.errors import InputError, UsageError

    meta_path = submission / "train" / "submission.json"
    for meta, message in (({**make.META, "use_lidar": 1}, "meta.use_lidar must be true or false"),
                          ({**make.META, "task": "detection"}, "meta.task must be one of segmentation, tracking"),
                          ({"use_lidar": True}, "\"meta\" must hold exactly use_camera, use_lidar, use_radar, "
                                                "use_map, use_external \\(and optionally task\\)$")):
        meta_path.write_text(json.dumps({"meta": meta}))
        with pytest.raises(InputError, match=message):
            _evaluate(labelled_out, submission)
    meta_path.write_text("{not json")
    with pytest.raises(InputError, match="submission.json: cannot be read as JSON"):
        _evaluate(labelled_out, submission)
    meta_path.write_text(json.dumps({"meta": {**make.META, "task": "tracking"}}))
    with pytest.raises(UsageError) as caught:
        _evaluate(labelled_out, submission)
    assert str(caught.value) == (f"{submission / 'train' / 'submission.json'} is a tracking submission: "
                                 "evaluate it with --task panoptic-tracking")
    _evaluate(labelled_out, submission, task="panoptic-tracking")  # the task the devkit's main would take
    meta_path.unlink()
    with pytest.raises(InputError, match="submission.json does not exist"):
        _evaluate(labelled_out, submission)
    with pytest.raises(UsageError, match="a panoptic submission is a folder"):
        _evaluate(labelled_out, _first_file(submission)[0])


def test_settings_that_do_not_apply_are_refused(labelled_out, submission):
    from nuparquet.errors import UsageError

    with pytest.raises(UsageError, match="--config and --config-file do not apply to --task panoptic"):
        _evaluate(labelled_out, submission, config="detection_cvpr_2019")
    with pytest.raises(UsageError, match="--by distance: --task panoptic slices by location, night, rain, scene"):
        _evaluate(labelled_out, submission, by=("distance",))
    with pytest.raises(UsageError, match="--min-inst-points must be 0 or more"):
        _evaluate(labelled_out, submission, min_inst_points=-1)
    with pytest.raises(UsageError, match="evaluates --task panoptic or panoptic-tracking, not lidarseg"):
        _evaluate(labelled_out, submission, task="lidarseg")
    import nuparquet

    for task in ("detection", "lidarseg"):  # the minimum is the panoptic tasks' alone
        with pytest.raises(UsageError, match=f"--min-inst-points applies to --task panoptic and panoptic-tracking, "
                           f"not {task}"):
            nuparquet.evaluate(labelled_out, submission, task=task, min_inst_points=16)


def test_a_split_without_thing_instances_is_refused_for_tracking(labelled_out, submission, monkeypatch):
    """The devkit's TQ divides a Python 0.0 by 0 there (ZeroDivisionError): a clear error instead."""
    from nuparquet.errors import InputError

    with pytest.raises(InputError, match="no ground-truth thing instance has more than min_inst_points=100000"):
        _evaluate(labelled_out, submission, task="panoptic-tracking", min_inst_points=100000)
    seg = _evaluate(labelled_out, submission, min_inst_points=100000)  # segmentation: no FN nor FP counted
    assert seg.classes["fn"].sum() == 0 and seg.classes["fp"].sum() == 0


def test_the_one_verb_and_the_cli_write_the_devkit_file(labelled_out, devkit_nusc, submission, tmp_path,
                                                         monkeypatch, capsys):
    import nuparquet
    from nuparquet.cli.main import main

    theirs, _ = devkit_panoptic(devkit_nusc, submission, "tracking", 15, tmp_path / "devkit", monkeypatch)
    front = nuparquet.evaluate(labelled_out, submission, tmp_path / "front", task="panoptic-tracking", split="train")
    assert_equal_to_devkit(front.metrics, theirs)
    written = (tmp_path / "front" / "tracking-result.json").read_text()
    assert sorted(p.name for p in (tmp_path / "front").iterdir()) == ["classes.parquet", "instances.parquet",
                                                                     "plots", "tracking-result.json"]
    assert main(["eval", str(labelled_out), "--task", "panoptic-tracking", "--results", str(submission),
                 "--split", "train", "--out", str(tmp_path / "cli"), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert (tmp_path / "cli" / "tracking-result.json").read_text() == written
    assert "Panoptic nuScenes tracking:" in printed and "PAT: " in printed and "driveable_surface" in printed
    assert main(["eval", str(labelled_out), "--task", "panoptic", "--results", str(submission), "--split", "train",
                 "--out", str(tmp_path / "seg"), "--min-inst-points", "40", "--quiet"]) == 0
    seg_theirs, _ = devkit_panoptic(devkit_nusc, submission, "segmentation", 40, tmp_path / "devkit40", monkeypatch)
    assert_equal_to_devkit(json.loads((tmp_path / "seg" / "segmentation-result.json").read_text()), seg_theirs)
    # an evaluation into a folder that holds one: refused, then replaced whole with --overwrite (the old files gone)
    args = ["eval", str(labelled_out), "--task", "panoptic", "--results", str(submission), "--split", "train",
            "--out", str(tmp_path / "seg"), "--quiet"]
    assert main(args) == 2
    (tmp_path / "seg" / "stale.txt").write_text("from before")
    assert main([*args, "--overwrite"]) == 0
    assert sorted(p.name for p in (tmp_path / "seg").iterdir()) == ["classes.parquet", "instances.parquet",
                                                                   "plots", "segmentation-result.json"]
    seg_default, _ = devkit_panoptic(devkit_nusc, submission, "segmentation", 15, tmp_path / "devkit15", monkeypatch)
    assert_equal_to_devkit(json.loads((tmp_path / "seg" / "segmentation-result.json").read_text()), seg_default)


def test_a_label_no_category_maps_is_named_by_its_first_point():
    """The refusal names the first point whose category index maps to nothing: its label, its place, its index."""
    import types

    from nuparquet.errors import InputError
    from nuparquet.evaluation.panoptic import run

    labels = np.array([1001, 5003, 5007, 2000])
    ds = types.SimpleNamespace(sensors=types.SimpleNamespace(labels=lambda token, kind: labels))
    lookup = np.array([0, 1, 2, -1, -1, -1])
    with pytest.raises(InputError) as caught:
        run._ground_truth(ds, "tok", lookup)
    assert str(caught.value) == ("panoptic label 5003 at point 1 of lidar sample_data tok: category index 5 is the "
                                 "index of no category")
    assert run._ground_truth(ds, "tok", np.array([0, 1, 2, 3, 4, 5])) is labels


def test_labels_no_category_maps_and_a_dataset_without_panoptic_are_refused(labelled_out, submission, monkeypatch):
    import nuparquet
    from nuparquet.dataset.core import Dataset
    from nuparquet.errors import InputError, UsageError
    from nuparquet.evaluation.panoptic import run

    ds = nuparquet.open(labelled_out)
    lookup = run.fine_to_coarse_lookup(ds)
    with monkeypatch.context() as patch:
        unmapped = lookup.copy()
        unmapped[:] = -1  # as if no category held any index the labels use
        patch.setattr(run, "fine_to_coarse_lookup", lambda dataset: unmapped)
        with pytest.raises(InputError, match="panoptic label .* at point 0 of lidar sample_data .*: category index "
                           ".* is the index of no category"):
            _evaluate(labelled_out, submission)
        patch.setattr(run, "fine_to_coarse_lookup", lambda dataset: lookup[:1])  # shorter than the indices used
        with pytest.raises(InputError, match="is the index of no category"):
            _evaluate(labelled_out, submission)
    names = [name for name in ds.datasets if name != "tables/panoptic"]
    monkeypatch.setattr(Dataset, "datasets", property(lambda self: names))
    with pytest.raises(UsageError, match="has no panoptic labels"):
        _evaluate(ds, submission)


@pytest.mark.parametrize("instances", [30, 300])  # 300 x 300 pairs: counted by a sort, not a table of them all
def test_a_frames_pairs_are_the_devkits_unique_combinations(instances):
    from nuparquet.evaluation.panoptic.segments import frame_segments

    rng = np.random.default_rng(instances)
    class_of = np.arange(32) % 17  # fine index -> coarse class (0: ignored)
    gt = rng.choice([1, 2, 3, 4], 2 * instances) * 1000 + rng.integers(1, instances + 1, 2 * instances)
    pred = rng.integers(1, 5, 2 * instances) * 1000 + rng.integers(0, instances, 2 * instances)
    seg = frame_segments(gt, pred, class_of)
    offset = 2 ** 32  # the devkit's key: prediction + offset * ground truth, each + 1
    combos, counts = np.unique((pred + 1) + offset * (gt + 1), return_counts=True)
    assert (seg.gt_ids[seg.pair_gt] + 0).tolist() == (combos // offset).tolist()
    assert seg.pred_ids[seg.pair_pred].tolist() == (combos % offset).tolist()
    assert seg.pair_points.tolist() == counts.tolist()
    ids, points = np.unique(gt + 1, return_counts=True)
    assert seg.gt_ids.tolist() == ids.tolist() and seg.gt_points.tolist() == points.tolist()


def test_the_class_table_says_which_classes_are_things_and_stuff(labelled_out, devkit_nusc, submission):
    from nuscenes.eval.panoptic.utils import PanopticClassMapper

    mapper = PanopticClassMapper(devkit_nusc)
    result = _evaluate(labelled_out, submission, task="panoptic-tracking")
    classes = result.classes
    assert classes.columns[:7] == ["class_index", "class", "kind", "tp", "fp", "fn", "iou_sum"]
    kinds = dict(zip(classes["class"].to_list(), classes["kind"].to_list()))
    assert {name for name, kind in kinds.items() if kind == "thing"} == set(mapper.things)
    assert {name for name, kind in kinds.items() if kind == "stuff"} == set(mapper.stuff)
    assert [name for name, kind in kinds.items() if kind == "ignore"] == [mapper.ignore_class["name"]]
    # both sides of a match say TP; a matched prediction names the ground truth it matched, with the same IoU
    instances = result.instances
    tp_gt = instances.filter((instances["side"] == "gt") & (instances["term"] == "TP")).sort("sample_data_token",
                                                                                               "label")
    tp_pred = instances.filter((instances["side"] == "pred") & (instances["term"] == "TP"))
    assert tp_gt.height == tp_pred.height == classes["tp"].sum() > 0
    joined = tp_gt.join(tp_pred, left_on=["sample_data_token", "label"],
                        right_on=["sample_data_token", "matched_label"], suffix="_pred")
    assert joined.height == tp_gt.height
    assert (joined["matched_label"] == joined["label_pred"]).all() and (joined["iou"] == joined["iou_pred"]).all()
    assert instances.filter(instances["term"].is_null())["matched_label"].is_null().all()
