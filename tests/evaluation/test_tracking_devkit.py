"""The tracking evaluation against nuscenes-devkit's own `TrackingEval` (motmetrics 1.4.0) on the edited synthetic
set, with seeded edge submissions (tests/evaluation/tracking_submissions.py): both JSON files, every key in the
devkit's order, every value equal (integers staying integers) except the MOTP family, which the devkit computes
from a BLAS distance product (within 1e-7 m; see docs/CONTRACTS.md). The devkit's metrics_details.json orders
the metrics of a class by a Python set (its order changes with the string hash seed): those keys are compared as
a set, after confidence and recall_hypo."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

pytestmark = pytest.mark.devkit

INEXACT = ("motp", "amotp")  # the values the devkit's BLAS distances reach
TOLERANCE_M = 1e-7


@pytest.fixture(scope="module")
def tracking_make():
    import tracking_submissions

    return tracking_submissions


def devkit_tracking(root: Path, results: Path, out: Path, config_file: Path | None = None,
                    keep=None) -> tuple[dict, dict]:
    """The devkit's TrackingEval.main (no plots) written to `out`, read back; `keep(box) -> bool` filters its
    ground truth and predictions after its own filters (a slice)."""
    from nuscenes.eval.common.config import config_factory
    from nuscenes.eval.tracking.data_classes import TrackingConfig
    from nuscenes.eval.tracking.evaluate import TrackingEval

    config = (config_factory("tracking_nips_2019") if config_file is None
              else TrackingConfig.deserialize(json.loads(Path(config_file).read_text())))
    if keep is None:
        evaluation = TrackingEval(config, str(results), "val", str(out), "v1.0-trainval", str(root), verbose=False)
    else:
        from nuscenes.eval.tracking import evaluate as devkit_evaluate

        original = devkit_evaluate.filter_eval_boxes

        def filtered(nusc, boxes, *args, **kwargs):
            boxes = original(nusc, boxes, *args, **kwargs)
            for token in boxes.sample_tokens:
                boxes.boxes[token] = [b for b in boxes.boxes[token] if keep(b)]
            return boxes

        devkit_evaluate.filter_eval_boxes = filtered
        try:
            evaluation = TrackingEval(config, str(results), "val", str(out), "v1.0-trainval", str(root),
                                      verbose=False)
        finally:
            devkit_evaluate.filter_eval_boxes = original
    evaluation.main(render_curves=False)
    return (json.loads((out / "metrics_summary.json").read_text()),
            json.loads((out / "metrics_details.json").read_text()))


def compare(ours, theirs, path: str = "") -> list[str]:
    """Equal structure and values (see the module docstring); returns the paths of inexact values."""
    inexact = []
    if isinstance(theirs, dict):
        assert isinstance(ours, dict), path
        if path.startswith("details/") and path.count("/") == 1:  # details/<class>: the devkit's set order
            assert list(ours)[:2] == list(theirs)[:2] == ["confidence", "recall_hypo"], path
            assert set(ours) == set(theirs), path
        else:
            assert list(ours) == list(theirs), f"{path}: keys {list(ours)} != {list(theirs)}"
        for key in theirs:
            inexact += compare(ours[key], theirs[key], f"{path}/{key}")
    elif isinstance(theirs, list):
        assert isinstance(ours, list) and len(ours) == len(theirs), f"{path}: lengths differ"
        for i, (a, b) in enumerate(zip(ours, theirs)):
            inexact += compare(a, b, f"{path}[{i}]")
    elif path.endswith("eval_time"):
        assert isinstance(ours, float)
    elif isinstance(theirs, float):
        assert type(ours) is float, f"{path}: {ours!r} is not a float like the devkit's {theirs!r}"
        if math.isnan(theirs):
            assert math.isnan(ours), f"{path}: {ours} != NaN"
        elif ours != theirs:
            assert any(f"/{name}" in path for name in INEXACT), f"{path}: {ours!r} != {theirs!r}"
            assert abs(ours - theirs) <= TOLERANCE_M, f"{path}: {ours} != {theirs}"
            inexact.append(path)
    else:
        assert ours == theirs and type(ours) is type(theirs), f"{path}: {ours!r} != {theirs!r}"
    return inexact


def assert_same(out: Path, summary: dict, details: dict) -> None:
    ours_summary = json.loads((out / "metrics_summary.json").read_text())
    ours_details = json.loads((out / "metrics_details.json").read_text())
    compare(ours_summary, summary, "summary")
    compare(ours_details, details, "details")


@pytest.fixture(scope="module")
def edge_run(eval_root, eval_out, eval_nusc, tracking_make, tmp_path_factory):
    from nuparquet.evaluation.tracking import evaluate_tracking

    folder = tmp_path_factory.mktemp("tracking-edges")
    results = tracking_make.write(folder / "edges.json", tracking_make.edge_submission(eval_nusc, seed=1))
    summary, details = devkit_tracking(eval_root, results, folder / "devkit")
    ours = evaluate_tracking(eval_out, results, folder / "ours", plots=False)
    return results, summary, details, ours, folder


def test_edge_submission_equals_the_devkit(edge_run):
    _, summary, details, ours, folder = edge_run
    assert_same(folder / "ours", summary, details)
    assert json.loads(json.dumps(ours.summary)).keys() == summary.keys()


def test_the_edge_submission_reaches_the_edges(edge_run):
    """Preconditions: the devkit's result shows every case the submission was made for."""
    _, summary, details, _, _ = edge_run
    labels = summary["label_metrics"]
    assert summary["ids"] > 0 and summary["frag"] > 0 and summary["tid"] > 0 and summary["lgd"] > 0
    assert math.isnan(labels["amota"]["trailer"])  # no ground truth (the edits): every value NaN
    assert all(math.isnan(v) for v in details["trailer"]["mota"])
    assert labels["amota"]["bus"] == 0.0 and math.isnan(labels["fp"]["bus"])  # ground truth, no prediction
    assert labels["ml"]["bus"] > 0  # the worst value: every track lost
    levels = [t for t in details["car"]["confidence"] if not math.isnan(t)]
    assert len(set(levels)) < len(levels)  # scores on a grid: thresholds reached by several recall levels
    assert any(math.isnan(t) for t in details["car"]["confidence"])  # recall levels not reached


def test_a_class_reaching_every_recall_level_keeps_integer_counts(edge_run):
    """motmetrics' counts are int64: without a NaN beside them, metrics_details.json lists integers."""
    _, _, details, _, folder = edge_run
    ours = json.loads((folder / "ours" / "metrics_details.json").read_text())
    whole = [name for name, md in details.items() if not any(math.isnan(t) for t in md["confidence"])]
    assert whole, "no class reached every recall level"
    for name in whole:
        assert all(type(v) is int for v in details[name]["tp"]) and ours[name]["tp"] == details[name]["tp"]
        assert all(type(v) is int for v in ours[name]["ids"])


def test_ties_in_cost_went_to_the_assignment_solver(edge_run, eval_out):
    """The twins (hypotheses at exactly one spot) made frames where the solver chooses among equal costs; the
    equality above is then the solver's choice, as motmetrics makes it."""
    from nuparquet.dataset import open_dataset
    from nuparquet.evaluation.tracking.config import resolve_tracking_config
    from nuparquet.evaluation.tracking.inputs import evaluate_rows, prepare

    results = edge_run[0]
    config = resolve_tracking_config()
    inputs = prepare(open_dataset(eval_out), results, config, "val")
    evaluation, _, _ = evaluate_rows(inputs, inputs.gt_kept, inputs.pred_kept, config)
    solved = sum((c.data.events.solver_frames if c.data.events is not None else 0) + c.every.solver_frames
                 for c in evaluation.classes.values() if c.every is not None)
    assert solved > 0


def test_a_devkit_format_config_file(eval_root, eval_out, eval_nusc, tracking_make, tmp_path):
    """Another configuration: 12 thresholds, min recall 0.2, a 1.5 m match distance, worst values written as
    integers (they stay integers in the files) and a shorter range for pedestrians."""
    from importlib import resources

    from nuparquet.evaluation.tracking import evaluate_tracking

    config = json.loads((resources.files("nuparquet") / "data" / "tracking_nips_2019.json").read_text())
    config.update(num_thresholds=12, min_recall=0.2, dist_th_tp=1.5)
    config["metric_worst"].update(tid=20, lgd=20, motp=2)
    config["class_range"]["pedestrian"] = 30
    config_file = tmp_path / "config.json"
    config_file.write_text(json.dumps(config))
    results = tracking_make.write(tmp_path / "edges2.json", tracking_make.edge_submission(eval_nusc, seed=2))
    summary, details = devkit_tracking(eval_root, results, tmp_path / "devkit", config_file)
    evaluate_tracking(eval_out, results, tmp_path / "ours", config_file=config_file, plots=False)
    assert_same(tmp_path / "ours", summary, details)
    assert summary["cfg"]["num_thresholds"] == 12 and len(details["car"]["mota"]) == 12


def test_a_slice_equals_the_devkit_on_the_filtered_boxes(eval_root, eval_out, eval_nusc, edge_run, tmp_path):
    """--by scene: the slice's files are the devkit's evaluation of that scene's boxes (filtered after its own
    filters, before its tracks are made)."""
    from nuparquet.evaluation.tracking import evaluate_tracking

    results = edge_run[0]
    config_file = tmp_path / "config.json"
    from importlib import resources

    config = json.loads((resources.files("nuparquet") / "data" / "tracking_nips_2019.json").read_text())
    config["num_thresholds"] = 8
    config_file.write_text(json.dumps(config))
    ours = evaluate_tracking(eval_out, results, tmp_path / "ours", config_file=config_file, by=("scene",),
                             plots=False)
    scene = ours.slices["slice"][1]
    samples = {s["token"] for s in eval_nusc.sample if eval_nusc.get("scene", s["scene_token"])["name"] == scene}
    summary, details = devkit_tracking(eval_root, results, tmp_path / "devkit", config_file,
                                       keep=lambda box: box.sample_token in samples)
    folder = tmp_path / "ours" / "slices" / "scene" / scene
    assert_same(folder, summary, details)
    row = ours.slices.row(1, named=True)
    assert row["amota"] == summary["amota"] or (math.isnan(row["amota"]) and math.isnan(summary["amota"]))
    # each evaluated box is in the slice of its one scene: the counts add up to the boxes the tracks were made of
    # (their frames less the interpolated ones)
    assert ours.slices["num_gt"].sum() == (ours.tracks["boxes"] - ours.tracks["interpolated"]).sum() > 0
    predicted = ours.predicted_tracks
    assert ours.slices["num_predictions"].sum() == (predicted["boxes"] - predicted["interpolated"]).sum() > 0


def test_the_one_verb_and_the_cli_evaluate_tracking_as_evaluate_tracking_does(edge_run, eval_out, tmp_path, capsys):
    """`nuparquet.evaluate(ds, results, out, task="tracking")` and `nuparquet eval --task tracking` go to the same
    evaluation (the one front door): the same files, and the CLI prints the devkit's tracking summary."""
    import nuparquet
    from nuparquet.cli.main import main
    from nuparquet.evaluation.tracking.output import format_summary

    results, _, _, ours, folder = edge_run
    front = nuparquet.evaluate(eval_out, results, tmp_path / "front", task="tracking", plots=False)
    assert {k: v for k, v in front.summary.items() if k != "eval_time"} == \
        {k: v for k, v in ours.summary.items() if k != "eval_time"}
    assert main(["eval", str(eval_out), "--task", "tracking", "--results", str(results), "--out",
                 str(tmp_path / "cli"), "--no-plots", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "AMOTA" in printed and format_summary(front.summary).splitlines()[0] in printed
    for name in ("metrics_details.json",):
        assert (tmp_path / "cli" / name).read_text() == (folder / "ours" / name).read_text()


def test_the_track_table_gives_each_evaluated_class_its_best_mota_threshold_and_tracked_ratio(edge_run):
    """tracks: every ground-truth track of a class that has a best-MOTA threshold carries it (the devkit's
    metrics_details confidence at its highest MOTA) and its tracked ratio ((matched + switches) / boxes, what
    motmetrics' mostly-tracked count reads: as many tracks at 0.8 or more as the devkit's MT)."""
    import numpy as np
    import polars as pl

    _, summary, details, ours, _ = edge_run
    tracks = ours.tracks
    checked = 0
    for name, md in details.items():
        rows = tracks.filter(tracks["tracking_name"] == name)
        mota = np.array(md["mota"], dtype=np.float64)
        if np.all(np.isnan(mota)) or rows.height == 0:
            continue
        best = md["confidence"][int(np.nanargmax(mota))]
        if math.isnan(best):  # no prediction reached a recall level (bus): no threshold, nothing tracked
            assert rows["threshold"].null_count() == rows["tracked_ratio"].null_count() == rows.height, name
            continue
        assert rows["threshold"].to_list() == pytest.approx([best] * rows.height), name
        ratio = ((rows["matched"] + rows["switches"]) / rows["boxes"]).to_list()
        assert rows["tracked_ratio"].to_list() == pytest.approx(ratio), name
        assert int((rows["tracked_ratio"] >= 0.8).sum()) == summary["label_metrics"]["mt"][name], name
        # first_tracked: the frames before the first match, null exactly for the tracks never matched
        never = ((rows["matched"] + rows["switches"]) == 0).to_list()
        assert rows["first_tracked"].is_null().to_list() == never, name
        assert (rows["first_tracked"].drop_nulls() >= 0).all() and (rows["first_tracked"].drop_nulls()
                                                                     < rows.filter(~pl.Series(never))["boxes"]).all()
        checked += 1
    assert checked >= 2
