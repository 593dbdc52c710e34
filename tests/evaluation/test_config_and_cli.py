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
