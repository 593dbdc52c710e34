"""`render --predictions`: predicted boxes drawn beside the ground truth, in the cameras and the bird's-eye
view, projected as the ground truth is, coloured by what the evaluation made of them, on keyframes only."""

from __future__ import annotations

import dataclasses
import json

import cv2
import numpy as np
import polars as pl
import pytest

import nuparquet
from nuparquet.cli.main import main
from nuparquet.evaluation import evaluate
from nuparquet.evaluation.classes import CATEGORY_TO_DETECTION
from nuparquet.rendering import predictions as predicted
from nuparquet.rendering.video.pipeline import camera_plan
from nuparquet.rendering.video.scene import load_scene

SCENE = "scene-0001"  # the synthetic scenes are in the devkit's train list


def _bgr(rgb) -> tuple:
    return tuple(reversed(rgb))


@pytest.fixture(scope="module")
def results(synth_out, tmp_path_factory) -> tuple:
    """A submission for every sample: each detection-class annotation of scene-0001 as predicted exactly (scores
    0.2 .. 1.0), plus a false positive 20 m from the first box of each sample and one box far out of range."""
    annotations = pl.read_parquet(synth_out / "annotations")
    samples = pl.read_parquet(synth_out / "tables" / "sample")
    boxes = {token: [] for token in samples["token"]}
    rng = np.random.default_rng(0)
    for row in annotations.iter_rows(named=True):
        name = CATEGORY_TO_DETECTION.get(row["category_name"])
        if name is None:
            continue
        boxes[row["sample_token"]].append({
            "sample_token": row["sample_token"], "translation": list(row["translation"]), "size": list(row["size"]),
            "rotation": list(row["rotation"]), "velocity": [0.0, 0.0], "detection_name": name,
            "detection_score": float(rng.uniform(0.2, 1.0)), "attribute_name": ""})
    for token, listed in boxes.items():
        if listed:
            first = listed[0]
            for dx, score in ((20.0, 0.9), (500.0, 0.8)):
                boxes[token].append(dict(first, translation=[first["translation"][0] + dx, *first["translation"][1:]],
                                         detection_score=score))
    folder = tmp_path_factory.mktemp("render-predictions")
    path = folder / "results.json"
    path.write_text(json.dumps({"meta": {}, "results": boxes}))
    evaluate(synth_out, results=path, split="train", out=folder / "eval", plots=False)
    return path, folder / "eval"


def test_predictions_on_the_ground_truth_project_onto_its_outlines(synth_root, synth_out, results):
    """Predictions equal to the annotations draw exactly the annotations' wireframes (same projection)."""
    dataset = nuparquet.open(synth_out)
    rows = load_scene(dataset, SCENE, ["CAM_FRONT", "CAM_BACK"])
    detection = rows.annotations["category_name"].cast(pl.String).is_in(list(CATEGORY_TO_DETECTION))
    only_detection = dataclasses.replace(rows, annotations=rows.annotations.filter(detection))
    everything = predicted.load_predictions(results[0], dataset, SCENE, score_threshold=0.0)
    on_gt = np.isin(everything.translation_m[:, 0], only_detection.annotations["translation"].arr.get(0).to_numpy())
    exact = everything.take(on_gt)
    layout = (("CAM_FRONT", "CAM_BACK"),)
    plan = camera_plan(only_detection, layout, synth_root, scale=0.5, mosaic=True, all_frames=False, fps=2,
                       predictions=exact)
    drawn = 0
    for tile in plan.layout[0]:
        gt, ours = tile.overlay, tile.predictions
        for row in range(len(gt.row_start) - 1):
            a = gt.segments_px[gt.row_start[row]:gt.row_start[row + 1]]
            b = ours.segments_px[ours.row_start[row]:ours.row_start[row + 1]]
            assert sorted(map(bytes, a)) == sorted(map(bytes, b))
            drawn += len(b)
        assert (ours.colors_rgb == predicted.PREDICTED_RGB).all()
        assert all(label.rsplit(" ", 1)[1].replace(".", "").isdigit() for label in ours.labels)
    assert drawn > 10


def test_statuses_come_from_the_evaluation(synth_out, results):
    dataset = nuparquet.open(synth_out)
    loaded = predicted.load_predictions(results[1], dataset, SCENE, score_threshold=0.3)
    table = pl.read_parquet(results[1] / "predictions").filter(
        (pl.col("scene_name") == SCENE) & (pl.col("detection_score") >= 0.3))
    assert len(loaded) == table.height
    expected = np.where(~table["evaluated"].to_numpy(), predicted.FILTERED,
                        np.where(table["matched_gt_2m"].is_not_null().to_numpy(), predicted.TRUE_POSITIVE,
                                 predicted.FALSE_POSITIVE))
    np.testing.assert_array_equal(loaded.status, expected)
    assert set(loaded.status.tolist()) == {predicted.TRUE_POSITIVE, predicted.FALSE_POSITIVE, predicted.FILTERED}
    np.testing.assert_array_equal(loaded.colors_rgb(np.arange(len(loaded))), predicted.STATUS_RGB[expected])
    # from the submission itself: every box of the scene above the threshold, one colour
    plain = predicted.load_predictions(results[0], dataset, SCENE, score_threshold=0.5)
    assert len(plain) == table.filter(pl.col("detection_score") >= 0.5).height
    assert (plain.status == predicted.PREDICTED).all() and (plain.score >= 0.5).all()


def test_sweeps_show_no_predictions(synth_out, results):
    dataset = nuparquet.open(synth_out)
    rows = load_scene(dataset, SCENE, ["CAM_FRONT"], all_frames=True)
    loaded = predicted.load_predictions(results[0], dataset, SCENE, score_threshold=0.0)
    boxes, picked = predicted.prediction_boxes(rows.cameras, loaded)
    keyframe = rows.cameras["is_key_frame"].to_numpy()
    assert len(boxes) and keyframe[boxes.frame_index].all()
    assert (rows.cameras["sample_token"].to_numpy()[boxes.frame_index] == loaded.sample_token[picked]).all()
    assert len(boxes) == sum(int((loaded.sample_token == s).sum()) for s in rows.cameras.filter(
        pl.col("is_key_frame"))["sample_token"])


def _has(image: np.ndarray, rgb) -> bool:
    return bool((image == np.array(_bgr(rgb), dtype=np.uint8)).all(axis=2).any())


@pytest.mark.parametrize("channel", ["CAM_FRONT", "bev"])
def test_rendered_frames_tell_true_from_false_positives(channel, synth_out, results, tmp_path):
    frames = tmp_path / "frames"
    args = ["render", str(synth_out), "--scene", SCENE, "--channel", channel, "--frames-dir", str(frames),
            "--frame-format", "png", "--quiet"]
    assert main([*args, "--predictions", str(results[1]), "--score-threshold", "0"]) == 0
    images = [cv2.imread(str(p)) for p in sorted(frames.glob("*.png"))]
    assert images and all(_has(i[:100], predicted.TP_RGB) for i in images)  # the legend says what green is
    boxes = [i[100:] for i in images]  # below the legend: the boxes
    assert any(_has(i, predicted.TP_RGB) for i in boxes) and any(_has(i, predicted.FP_RGB) for i in boxes)
    plain = tmp_path / "plain"
    assert main([*args[:-5], "--frames-dir", str(plain), "--frame-format", "png", "--quiet"]) == 0
    images = [cv2.imread(str(p)) for p in sorted(plain.glob("*.png"))]
    assert not any(_has(i, predicted.TP_RGB) or _has(i, predicted.FP_RGB) for i in images)


def test_a_directory_that_is_not_an_evaluation_is_refused(synth_out, tmp_path, capsys):
    assert main(["render", str(synth_out), "--scene", SCENE, "--predictions", str(tmp_path), "--frames-dir",
                 str(tmp_path / "f"), "--quiet"]) == 2
    assert "not one written by `nuparquet eval`" in capsys.readouterr().err


def test_an_evaluation_directory_missing_its_predictions_or_its_summary_is_refused(results, tmp_path):
    """`nuparquet eval` writes predictions/*.parquet and metrics_summary.json: a directory holding one without the
    other is not read (neither half is enough), and the message names the directory and what it lacks."""
    import re
    import shutil

    from nuparquet.errors import UsageError

    evaluation = results[1]
    assert list((evaluation / "predictions").glob("*.parquet")) and (evaluation / "metrics_summary.json").is_file()
    predictions_only, summary_only = tmp_path / "predictions-only", tmp_path / "summary-only"
    shutil.copytree(evaluation / "predictions", predictions_only / "predictions")
    summary_only.mkdir()
    shutil.copy(evaluation / "metrics_summary.json", summary_only)
    for folder in (predictions_only, summary_only):
        message = (rf"^--predictions {re.escape(str(folder))}: a directory, but not one written by `nuparquet eval` "
                   r"\(no predictions/\*\.parquet and metrics_summary\.json\)$")
        with pytest.raises(UsageError, match=message):
            predicted.load_predictions(folder, None, SCENE)  # the dataset is read for a results.json only
    assert len(predicted.load_predictions(evaluation, None, SCENE, 0.0).score) > 0  # both halves: read


@pytest.fixture(scope="module")
def tracking_results(synth_out, results, tmp_path_factory):
    """The submission of `results` as tracks: each box's instance as its tracking_id (the false positives get ids
    of their own), tracking classes only."""
    from nuparquet.evaluation.classes import CATEGORY_TO_TRACKING

    annotations = pl.read_parquet(synth_out / "annotations").select("sample_token", "translation", "instance_token",
                                                                     "category_name")
    instance_at = {(r["sample_token"], tuple(r["translation"])): (r["instance_token"], r["category_name"])
                   for r in annotations.iter_rows(named=True)}
    content = json.loads(results[0].read_text())
    tracked = {}
    for token, boxes in content["results"].items():
        tracked[token] = []
        for i, box in enumerate(boxes):
            instance, category = instance_at.get((token, tuple(box["translation"])), (f"fp-{token[:4]}-{i}", None))
            name = CATEGORY_TO_TRACKING.get(category, "car") if category else "car"
            tracked[token].append({k: v for k, v in box.items() if k not in ("detection_name", "detection_score",
                                                                            "attribute_name")}
                                  | {"tracking_id": instance[:12], "tracking_name": name,
                                     "tracking_score": box["detection_score"]})
    path = tmp_path_factory.mktemp("render-tracks") / "tracks.json"
    path.write_text(json.dumps({"meta": {}, "results": tracked}))
    return path


def test_a_tracking_submission_draws_each_track_in_its_own_stable_colour(synth_out, tracking_results):
    import zlib

    dataset = nuparquet.open(synth_out)
    loaded = predicted.load_predictions(tracking_results, dataset, SCENE, score_threshold=0.0)
    assert loaded.tracking_id is not None and len(set(loaded.tracking_id.tolist())) > 5
    colors = loaded.colors_rgb(np.arange(len(loaded)))
    for track in set(loaded.tracking_id.tolist()):
        mine = colors[loaded.tracking_id == track]
        expected = predicted.TRACK_PALETTE_RGB[zlib.crc32(track.encode()) % len(predicted.TRACK_PALETTE_RGB)]
        assert (mine == expected).all()  # one colour along the track, the id's own
    assert len({tuple(c) for c in colors.tolist()}) > 3
    labels = loaded.labels(np.arange(len(loaded)))
    assert all(label.startswith(str(t)[:6] + " ") for label, t in zip(labels, loaded.tracking_id.tolist()))
    assert loaded.legend()[0][0] == "predicted track: one colour per id"


@pytest.mark.parametrize("channel", ["CAM_FRONT", "bev"])
def test_rendered_tracks_show_their_colours_and_a_legend(channel, synth_out, tracking_results, tmp_path):
    frames = tmp_path / "frames"
    assert main(["render", str(synth_out), "--scene", SCENE, "--channel", channel, "--frames-dir", str(frames),
                 "--frame-format", "png", "--quiet", "--predictions", str(tracking_results),
                 "--score-threshold", "0"]) == 0
    images = [cv2.imread(str(p)) for p in sorted(frames.glob("*.png"))]
    dataset = nuparquet.open(synth_out)
    loaded = predicted.load_predictions(tracking_results, dataset, SCENE, score_threshold=0.0)
    used = {tuple(c) for c in loaded.colors_rgb(np.arange(len(loaded))).tolist()}
    for image in images:
        width = image.shape[1]
        corner = image[:60, width - 300:]  # the legend's stripes: the first six palette colours
        assert all(_has(corner, tuple(c)) for c in predicted.TRACK_PALETTE_RGB[:6].tolist())
    assert sum(_has(i[100:], c) for i in images for c in used) >= 3  # boxes in their tracks' colours
