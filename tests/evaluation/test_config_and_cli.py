"""Configurations (by name, from a devkit-format file, refused when wrong), the `nuparquet eval` command (files,
printout, exit codes, --overwrite), the plots, and custom splits from <dataroot>/<version>/splits.json."""

from __future__ import annotations

import json
import shutil
from importlib import resources

import cv2
import pytest
from eval_reference import assert_same_metrics, devkit_eval, devkit_metrics
from eval_submissions import perfect, split_samples, write

from nuparquet.cli.main import main
from nuparquet.errors import UsageError
from nuparquet.evaluation import evaluate
from nuparquet.evaluation.classes import DETECTION_NAMES
from nuparquet.evaluation.config import named_config


def _cvpr() -> dict:
    return json.loads((resources.files("nuparquet") / "data" / "detection_cvpr_2019.json").read_text())


def test_the_named_configuration_is_the_devkits():
    from nuscenes.eval.detection.config import config_factory

    assert named_config("detection_cvpr_2019").serialize() == config_factory("detection_cvpr_2019").serialize()


def test_a_configuration_file_is_evaluated_as_the_devkit_does(submissions, eval_out, eval_nusc, tmp_path):
    config = _cvpr()
    config.update(dist_ths=[1, 2, 3], dist_th_tp=2, min_recall=0.2, min_precision=0.05, mean_ap_weight=3,
                  class_range={**config["class_range"], "car": 25, "pedestrian": 30.5})
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    summary, details = devkit_metrics(devkit_eval(eval_nusc, submissions["noisy"], tmp_path / "devkit",
                                                  config_file=path))
    evaluate(eval_out, results=submissions["noisy"], split="val", out=tmp_path / "ours", config_file=path, plots=False)
    assert "car:1" in details  # integer thresholds keep their spelling in the keys
    assert_same_metrics(tmp_path / "ours", summary, details)


@pytest.mark.parametrize("change, message", [
    (lambda c: c["class_range"].pop("car"), "class_range must give a range"),
    (lambda c: c.update(dist_th_tp=3.0), "dist_th_tp must be one of"),
    (lambda c: c.update(dist_fcn="iou"), "dist_fcn must be one of"),
    (lambda c: c.update(min_precision=1.0), "min_precision must be in"),
    (lambda c: c.update(max_boxes_per_sample=0), "max_boxes_per_sample must be a positive integer"),
    (lambda c: c.pop("mean_ap_weight"), "missing mean_ap_weight"),
])
def test_a_wrong_configuration_is_refused(change, message, tmp_path, submissions, eval_out):
    config = _cvpr()
    change(config)
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    with pytest.raises(UsageError, match=message):
        evaluate(eval_out, results=submissions["noisy"], config_file=path)


def test_unknown_names_are_usage_errors(submissions, eval_out):
    with pytest.raises(UsageError, match="unknown configuration"):
        evaluate(eval_out, results=submissions["noisy"], config="detection_2025")
    with pytest.raises(UsageError, match="unknown split 'holdout'"):
        evaluate(eval_out, results=submissions["noisy"], split="holdout")
    with pytest.raises(UsageError, match="holds none of the dataset's"):
        evaluate(eval_out, results=submissions["noisy"], split="mini_val")


def test_cli_writes_the_devkits_files_and_plots(submissions, eval_out, tmp_path, capsys):
    out = tmp_path / "eval"
    code = main(["eval", str(eval_out), "--results", str(submissions["noisy"]), "--split", "val", "--out", str(out),
                 "--by", "distance,night", "--quiet"])
    assert code == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "metrics_summary.json").read_text())
    assert f"mAP: {summary['mean_ap']:.4f}" in printed and f"NDS: {summary['nd_score']:.4f}" in printed
    assert "Slices by distance:" in printed and "Slices by night:" in printed and "note: split val lists 150" in printed
    assert (out / "metrics_details.json").is_file() and (out / "slices.parquet").is_file()
    names = ["summary", *(f"{n}_{kind}" for n in DETECTION_NAMES for kind in ("pr", "tp")),
             *(f"dist_pr_{t}" for t in (0.5, 1.0, 2.0, 4.0))]
    for name in names:
        image = cv2.imread(str(out / "plots" / f"{name}.png"))
        assert image is not None and image.shape[0] > 100 and image.std() > 0, name
    assert sorted(p.stem for p in (out / "plots").iterdir()) == sorted(names)
    # an output that holds files is not replaced without --overwrite
    again = ["eval", str(eval_out), "--results", str(submissions["perfect"]), "--out", str(out), "--quiet",
             "--no-plots"]
    assert main(again) == 2
    assert json.loads((out / "metrics_summary.json").read_text()) == summary
    assert main([*again, "--overwrite"]) == 0
    assert json.loads((out / "metrics_summary.json").read_text()) != summary
    assert not (out / "plots").exists() and not list(tmp_path.glob(".eval.*"))


def test_the_printout_is_the_devkits_main_for_the_same_summary(tmp_path, capsys):
    """`nuparquet eval` prints what `DetectionEval.main` prints: the devkit's own printing code is run (its
    evaluation replaced by the summary), so headers, names, formats and column order are compared, not restated.
    Every number differs, so a swapped or dropped error shows; NaN as the devkit prints the undefined errors."""
    from nuscenes.eval.detection.evaluate import DetectionEval

    from nuparquet.cli.eval import print_summary
    from nuparquet.evaluation.classes import TP_METRICS, UNDEFINED_TP_METRICS

    names = ["car", "pedestrian", "traffic_cone", "barrier"]
    errors = {name: {metric: (float("nan") if metric in UNDEFINED_TP_METRICS.get(name, ()) else
                              0.1 * (i + 1) + 0.01 * (j + 1) + 0.0004) for j, metric in enumerate(TP_METRICS)}
              for i, name in enumerate(names)}
    summary = {"mean_dist_aps": {name: 0.9 - 0.13 * i for i, name in enumerate(names)},
               "label_tp_errors": errors, "mean_ap": 0.51234, "nd_score": 0.60125, "eval_time": 12.34,
               "tp_errors": {metric: 0.2 + 0.05 * j for j, metric in enumerate(TP_METRICS)}}

    class Serialized:
        def __init__(self, value):
            self.value = value

        def serialize(self):
            return dict(self.value)

    devkit = DetectionEval.__new__(DetectionEval)  # only main's printing and files: no dataset to load
    devkit.output_dir, devkit.verbose, devkit.meta = str(tmp_path), False, {}
    devkit.evaluate = lambda: (Serialized(summary), Serialized({}))
    capsys.readouterr()
    devkit.main(render_curves=False)
    expected = capsys.readouterr().out
    print_summary(summary)
    printed = capsys.readouterr().out
    assert "AOE" in expected and "nan" in expected and f"{errors['car']['attr_err']:.3f}" in expected
    assert printed == expected


def test_cli_names_the_bad_sample_and_exits_1(submissions, eval_out, tmp_path, capsys):
    data = json.loads(submissions["noisy"].read_text())
    token = next(iter(data["results"]))
    data["results"][token][0]["detection_name"] = "tram"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    assert main(["eval", str(eval_out), "--results", str(bad), "--quiet"]) == 1
    assert f"sample {token} box 0: unknown detection_name 'tram'" in capsys.readouterr().err
    assert main(["eval", str(eval_out), "--results", str(submissions["noisy"]), "--split", "nope", "--quiet"]) == 2
    assert "unknown split 'nope'" in capsys.readouterr().err


def test_a_custom_split_is_read_from_the_dataroot(eval_root, eval_out, eval_nusc, tmp_path):
    """The devkit's custom splits: <dataroot>/<version>/splits.json; samples outside the split are ignored."""
    names = ["scene-0003", "scene-0007"]
    splits = eval_root / "v1.0-trainval" / "splits.json"
    splits.write_text(json.dumps({"mine": names}))
    try:
        results = perfect(eval_nusc, "val")  # scene-0003 and two others of val...
        for sample in split_samples(eval_nusc, "train"):  # ... and every train sample: scene-0007 among them
            results[sample["token"]] = []
        path = write(tmp_path / "results.json", results)
        summary, details = devkit_metrics(devkit_eval(eval_nusc, path, tmp_path / "devkit", split="mine"))
        result = evaluate(eval_out, results=path, split="mine", out=tmp_path / "ours", plots=False)
        assert_same_metrics(tmp_path / "ours", summary, details)
        assert set(result.predictions["scene_name"]) == {"scene-0003"}  # scene-0007's lists are empty
        assert set(result.ground_truth["scene_name"]) == set(names)
    finally:
        splits.unlink()


def test_without_out_nothing_is_written(submissions, eval_out, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = evaluate(eval_out, results=submissions["perfect"], split="val")
    assert result.out is None and not list(tmp_path.iterdir())
    with pytest.raises(UsageError, match="converted dataset"):
        evaluate(eval_out, results=submissions["perfect"], out=eval_out / "eval")
    shutil.rmtree(eval_out / "eval", ignore_errors=True)


def test_a_split_missing_from_splits_json_is_refused_listing_the_splits_it_has(tmp_path):
    """A custom split is looked up in <dataroot>/<version>/splits.json: the error for one it lacks lists the
    splits the file has (sorted), or none when the file is not an object of lists; a split it has is returned."""
    from nuparquet.evaluation.splits import split_scene_names

    folder = tmp_path / "v1.0-custom"
    folder.mkdir()
    (folder / "splits.json").write_text(json.dumps({"night": ["scene-0002"], "dusk": ["scene-0001", "scene-0003"]}))
    assert split_scene_names("dusk", dataroot=str(tmp_path), version="v1.0-custom") == ["scene-0001", "scene-0003"]
    with pytest.raises(UsageError, match=r"unknown split 'rain': not predefined, nor in .*splits.json "
                                         r"\(it lists: dusk, night\)"):
        split_scene_names("rain", dataroot=str(tmp_path), version="v1.0-custom")
    (folder / "splits.json").write_text(json.dumps(["scene-0001"]))
    with pytest.raises(UsageError, match=r"\(it lists: none\)"):
        split_scene_names("rain", dataroot=str(tmp_path), version="v1.0-custom")


@pytest.mark.parametrize("field, value, accepted", [
    ("min_recall", 0, True), ("min_recall", 1, True), ("min_recall", -0.01, False), ("min_recall", 1.01, False),
    ("min_precision", 0, True), ("min_precision", 0.99, True), ("min_precision", -0.01, False),
])
def test_the_clips_are_accepted_within_the_devkits_bounds(field, value, accepted):
    """min_recall in [0, 1] and min_precision in [0, 1): the devkit's calc_ap asserts exactly these bounds
    (`0 <= min_recall <= 1`, `0 <= min_precision < 1`), so a file it evaluates is not refused here."""
    from nuparquet.evaluation.config import DetectionConfig

    content = {**_cvpr(), field: value}
    if accepted:
        assert getattr(DetectionConfig.from_dict(content), field) == value
    else:
        with pytest.raises(UsageError, match=f"{field} must be in"):
            DetectionConfig.from_dict(content)


def test_evaluate_takes_an_opened_dataset_as_it_takes_its_path(submissions, eval_out):
    """`evaluate(dataset, ...)` with a `Dataset` from nuparquet.open gives what `evaluate(path, ...)` gives."""
    import nuparquet

    by_path = evaluate(eval_out, results=submissions["noisy"], split="val", plots=False)
    opened = evaluate(nuparquet.open(eval_out), results=submissions["noisy"], split="val", plots=False)
    assert {k: v for k, v in opened.summary.items() if k != "eval_time"} == \
        {k: v for k, v in by_path.summary.items() if k != "eval_time"}
    assert opened.details == by_path.details


def test_settings_beside_an_options_object_are_used_and_a_contradiction_is_refused(submissions, eval_out):
    """`evaluate(ds, results, options=EvalOptions(...), **keywords)` merges the two as every verb does (a keyword
    passed beside an options object used to be dropped silently): the keyword split takes effect, and a keyword
    that says otherwise than a field the object set is an error naming it."""
    from nuparquet.evaluation.options import EvalOptions

    with pytest.raises(UsageError, match="holds none of the dataset.s"):  # the keyword split is the one checked
        evaluate(eval_out, submissions["noisy"], None, EvalOptions(plots=False), split="mini_val")
    merged = evaluate(eval_out, submissions["noisy"], None, EvalOptions(split="val"), plots=False, by=("night",))
    alone = evaluate(eval_out, submissions["noisy"], split="val", plots=False, by=("night",))
    assert merged.slices is not None and merged.slices.equals(alone.slices)  # the keyword `by` was not dropped
    with pytest.raises(TypeError, match="option\\(s\\) split given both in the EvalOptions object and as keywords"):
        evaluate(eval_out, submissions["noisy"], None, EvalOptions(split="val"), split="train")


def test_tp_curves_are_drawn_where_the_devkits_are(devkit):
    """`class_tp_curve` draws on an Axes what the devkit's `render.class_tp_curve` draws: a curve per TP metric up to
    the highest recall reached, none (label "n/a") for a metric undefined for the class (barrier: vel_err,
    attr_err are NaN), and none (label "nan") for every metric when the recall never reached min_recall (the devkit's
    calc_tp then gives 1.0, a number): the same lines, labels and y limit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from nuscenes.eval.common.config import config_factory
    from nuscenes.eval.detection import data_classes as their
    from nuscenes.eval.detection.render import class_tp_curve as their_curve

    from nuparquet.evaluation.metrics import DetectionMetrics, MetricData
    from nuparquet.evaluation.plots import class_tp_curve

    config, their_config = named_config("detection_cvpr_2019"), config_factory("detection_cvpr_2019")
    rng = np.random.default_rng(5)
    for name, reached, errors in (("barrier", 60, {"trans_err": 0.3, "scale_err": 0.2, "orient_err": 0.1,
                                                   "vel_err": np.nan, "attr_err": np.nan}),
                                  ("car", 7, dict.fromkeys(("trans_err", "vel_err", "scale_err", "orient_err",
                                                            "attr_err"), 1.0))):
        arrays = {"recall": np.linspace(0, 1, 101), "precision": rng.uniform(0, 1, 101),
                  "confidence": np.where(np.arange(101) <= reached, np.linspace(1, 0.01, 101), 0.0),
                  **{m: rng.uniform(0.05, 1.5, 101) for m in errors}}
        assert (round(100 * config.min_recall) <= reached) == (name == "barrier")  # the two cases
        theirs = their.DetectionMetrics(their_config)
        for metric, value in errors.items():
            theirs.add_label_tp(name, metric, value)
        md_list = their.DetectionMetricDataList()
        md_list.set(name, config.dist_th_tp, their.DetectionMetricData(**arrays))
        drawn = []
        for ours in (True, False):
            fig, ax = plt.subplots()
            if ours:
                class_tp_curve(ax, MetricData(**arrays), DetectionMetrics(config, {}, {name: errors}), name,
                               config.min_recall)
            else:
                their_curve(md_list, theirs, name, their_config.min_recall, their_config.dist_th_tp, ax=ax)
            drawn.append(([(line.get_xydata().tolist(), line.get_label()) for line in ax.get_lines()], ax.get_ylim()))
            plt.close(fig)
        assert drawn[0] == drawn[1]
        curves = [xy for xy, label in drawn[0][0] if not label.startswith("_")]  # not the max-recall line
        assert len(curves) == 5 and sum(len(xy) > 0 for xy in curves) == (3 if name == "barrier" else 0)
