"""The real nuScenes extract (scene-0523, scene-0916: both in val, scene-0916 also in mini_val; scene-0916 has
bicycle racks, though no annotated cycle stands in one, so predicted bicycles are put in them): our metrics
against the devkit's, whose split check wants a version folder named for the split, so it reads the extract
through a symlinked v1.0-trainval / v1.0-mini folder."""

from __future__ import annotations

import polars as pl
import pytest
from eval_reference import assert_same_metrics, devkit_eval, devkit_metrics
from eval_submissions import noisy, perfect, write

from nuparquet.evaluation import evaluate

EXTRACT_VERSION = "v1.0-mini-extract"


@pytest.fixture(scope="module", params=[("val", "v1.0-trainval"), ("mini_val", "v1.0-mini")], ids=["val", "mini_val"])
def extract_nusc(request, devkit, extract_root, tmp_path_factory):
    split, version = request.param
    root = tmp_path_factory.mktemp(f"extract-{split}")
    (root / version).symlink_to(extract_root / EXTRACT_VERSION, target_is_directory=True)
    (root / "maps").symlink_to(extract_root / "maps", target_is_directory=True)
    return split, devkit.NuScenes(version, str(root), verbose=False)


@pytest.mark.parametrize("kind", ["perfect", "noisy"])
def test_real_extract_metrics_equal_the_devkit(kind, extract_nusc, extract_out, tmp_path):
    split, nusc = extract_nusc
    results = perfect(nusc, split) if kind == "perfect" else noisy(nusc, seed=5, split=split)
    racked = 0
    for token, boxes in results.items():
        for ann in (nusc.get("sample_annotation", a) for a in nusc.get("sample", token)["anns"]):
            if ann["category_name"] == "static_object.bicycle_rack":
                boxes.append({"sample_token": token, "translation": ann["translation"], "size": [0.6, 1.7, 1.3],
                              "rotation": ann["rotation"], "velocity": [0.0, 0.0], "detection_name": "bicycle",
                              "detection_score": 0.6, "attribute_name": "cycle.without_rider"})
                racked += 1
    path = write(tmp_path / "results.json", results)
    summary, details = devkit_metrics(devkit_eval(nusc, path, tmp_path / "devkit", split=split))
    result = evaluate(extract_out, results=path, split=split, out=tmp_path / "ours", plots=False)
    assert_same_metrics(tmp_path / "ours", summary, details)
    assert set(result.ground_truth["scene_name"]) == ({"scene-0916"} if split == "mini_val"
                                                      else {"scene-0523", "scene-0916"})
    in_racks = result.predictions.filter(pl.col("filtered_by") == "bike_rack").height
    assert 0 < racked and in_racks >= racked - result.predictions.filter(
        (pl.col("filtered_by") == "range") & (pl.col("detection_name") == "bicycle")).height
