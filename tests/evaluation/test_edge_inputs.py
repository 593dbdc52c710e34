"""Inputs at the edges: a submission without a single box (the devkit crashes on it; here every class scores
zero), and a dataset without annotations (a test version: nothing to evaluate against)."""

from __future__ import annotations

import json
import math

import pytest
from eval_submissions import split_samples

from nuparquet.errors import InputError
from nuparquet.evaluation import evaluate


def test_a_submission_without_boxes_scores_zero(eval_out, eval_nusc, tmp_path):
    path = tmp_path / "empty.json"
    path.write_text(json.dumps({"meta": {}, "results": {s["token"]: [] for s in split_samples(eval_nusc)}}))
    result = evaluate(eval_out, results=path, split="val", out=tmp_path / "out")
    summary = result.summary
    assert summary["mean_ap"] == 0.0 and summary["nd_score"] == 0.0
    assert all(v == 1.0 for v in summary["tp_errors"].values())
    assert math.isnan(summary["label_tp_errors"]["traffic_cone"]["orient_err"])
    assert result.predictions.height == 0 and (tmp_path / "out" / "plots" / "summary.png").is_file()
    gt = result.ground_truth
    assert gt.height > 0 and gt["matched_box_2m"].null_count() == gt.height


def test_a_dataset_without_annotations_cannot_be_evaluated(irregular_empty_out, tmp_path):
    path = tmp_path / "results.json"
    path.write_text(json.dumps({"meta": {}, "results": {}}))
    with pytest.raises(InputError, match="has no annotations"):
        evaluate(irregular_empty_out, results=path, split="train")


def test_progress_is_reported_step_by_step(submissions, eval_out, tmp_path):
    events = []
    evaluate(eval_out, results=submissions["noisy"], split="val", out=tmp_path / "out", by=("night",),
             on_progress=events.append)
    assert events[-1].finished and events[-1].done == events[-1].total
    steps = [e.step for e in events if e.step]
    assert steps[0] == "read the submission" and "match and score" in steps and "plots" in steps
    assert any(step.startswith("slice night") for step in steps)
    assert [e.done for e in events] == sorted(e.done for e in events)
    assert len({e.total for e in events if e.total is not None}) == 1  # a bar's total never changes midway


def test_progress_without_slices_names_each_stage_and_no_more(submissions, eval_out):
    """Without slices the total is known from the start (six steps without --out), every step is named by its
    stage, and the steps with nothing to do (no slices, nothing to write) say nothing."""
    events = []
    evaluate(eval_out, results=submissions["noisy"], split="val", on_progress=events.append)
    assert [e.step for e in events if e.step] == ["read the submission", "load the ground truth", "filter",
                                                  "match and score", "tables"]
    assert {e.total for e in events} == {6} and events[-1].finished and events[-1].done == 6
