"""The conversion's progress: the total is unknown while the tables are read, then set once with every unit still to
come (the tables written, each scene batch, each builder and its own units: one per scene of points, the batch of
rows of no scene) and never changed, so a bar never reads 97% and then 78% (issue 24: it grew 32 -> 40 -> 43 -> 46)."""

from __future__ import annotations

import pytest

import nuparquet
from conftest import SYNTH_VERSION
from nuparquet.progress import Progress, Reporter


def _events(root, version, out, **options):
    events = []
    nuparquet.convert(root, version, out, on_progress=events.append, **options)
    return events


def _check(events):
    totals = [e.total for e in events]
    known = [t for t in totals if t is not None]
    first = totals.index(known[0])
    assert all(t is None for t in totals[:first]) and set(totals[first:]) == {known[0]}  # set once, never changed
    assert first > 3  # unknown while the tables are read
    assert [e.done for e in events] == sorted(e.done for e in events)
    assert events[-1].finished and events[-1].done == events[-1].total
    return known[0]


def test_the_total_is_set_once_and_reached_with_points_of_every_scene(labelled_root, tmp_path):
    events = _events(labelled_root, SYNTH_VERSION, tmp_path / "out", sensors=("lidar", "radar"), workers=1,
                     scenes_per_batch=1)
    total = _check(events)
    steps = [e.step for e in events if e.step]
    # two scenes: a batch each, and a unit per scene for each points dataset
    assert sum(s.startswith("scene batch") for s in steps) == 2
    assert sum(s.startswith("lidar_points scene-") for s in steps) == 2
    assert sum(s.startswith("radar_points scene-") for s in steps) == 2
    without_points = _check(_events(labelled_root, SYNTH_VERSION, tmp_path / "plain", scenes_per_batch=1))
    assert total - without_points == 2 * (1 + 2)  # each points builder, and its two scenes


def test_the_total_counts_the_batch_of_rows_of_no_scene(tmp_path):
    """--allow-dangling: samples whose scene is absent form a last batch, counted before the run."""
    import json

    from nuparquet.synth import synthesize

    root = synthesize(tmp_path / "data", scenes=2, samples_per_scene=2, seed=1, version=SYNTH_VERSION,
                      with_can_bus=False)
    scenes = json.loads((root / SYNTH_VERSION / "scene.json").read_text())
    (root / SYNTH_VERSION / "scene.json").write_text(json.dumps(scenes[:1]))  # scene 2's samples now belong to none
    events = _events(root, SYNTH_VERSION, tmp_path / "out", allow_dangling=True, scenes_per_batch=1)
    _check(events)
    assert sum(e.step.startswith("scene batch") for e in events if e.step) == 2  # scene-0001's and the orphans'


def test_the_steps_name_every_table_read_then_the_integrity_check_and_end_with_the_manifest(synth_root, tmp_path):
    """What a progress bar shows: each table of the version folder read (by its name), the integrity check after the
    last one, and the manifest written last."""
    tables = sorted(path.stem for path in (synth_root / SYNTH_VERSION).glob("*.json"))
    steps = [e.step for e in _events(synth_root, SYNTH_VERSION, tmp_path / "out") if e.step]
    reads = [s for s in steps if s.startswith("read ")]
    assert sorted(s.removeprefix("read ") for s in reads) == tables
    assert steps[len(reads)] == "check integrity" and steps[:len(reads)] == reads
    assert steps[-1] == "write manifest" and steps.count("write manifest") == 1


def test_validate_steps_name_every_table_read_then_the_integrity_check(synth_root):
    """`validate`'s bar (the CLI's `validate` draws it): each table of the version folder read, by its name, then the
    integrity check, named as the conversion names it, and nothing after it; the bar ends finished."""
    tables = sorted(path.stem for path in (synth_root / SYNTH_VERSION).glob("*.json"))
    events = []
    assert not nuparquet.validate(synth_root, SYNTH_VERSION, on_progress=events.append).problems
    steps = [e.step for e in events if e.step]
    reads = steps[:-1]
    assert all(s.startswith("read ") for s in reads) and sorted(s.removeprefix("read ") for s in reads) == tables
    assert steps[-1] == "check integrity"
    assert {e.task for e in events} == {"validate"} and events[-1].finished


def test_allow_dangling_on_a_dataset_with_nothing_dangling_counts_no_batch_of_rows_of_no_scene(tmp_path):
    """`--allow-dangling` looks for per-sample rows of no scene in every per-sample table (samples by their token,
    the others by sample_token): a clean dataset has none, so its total is the same as without the option."""
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path / "data", scenes=2, samples_per_scene=2, seed=1, version=SYNTH_VERSION,
                      with_can_bus=False)
    plain = _check(_events(root, SYNTH_VERSION, tmp_path / "plain", scenes_per_batch=1))
    allowing = _events(root, SYNTH_VERSION, tmp_path / "allowing", allow_dangling=True, scenes_per_batch=1)
    assert _check(allowing) == plain
    assert sum(e.step.startswith("scene batch") for e in allowing if e.step) == 2  # one per scene, no orphans'


def test_annotations_of_an_absent_sample_form_the_batch_of_rows_of_no_scene(tmp_path):
    """An annotation whose sample is absent (every sample still in a scene): found through sample_token, so the
    rows of no scene get their own batch, counted before the run."""
    import json

    from nuparquet.synth import synthesize

    root = synthesize(tmp_path / "data", scenes=2, samples_per_scene=2, seed=1, version=SYNTH_VERSION,
                      with_can_bus=False)
    path = root / SYNTH_VERSION / "sample_annotation.json"
    annotations = json.loads(path.read_text())
    annotations[0]["sample_token"] = "f" * 32  # no such sample
    path.write_text(json.dumps(annotations))
    events = _events(root, SYNTH_VERSION, tmp_path / "out", allow_dangling=True, scenes_per_batch=1)
    _check(events)
    assert sum(e.step.startswith("scene batch") for e in events if e.step) == 3  # two scenes' and the orphans'


def test_a_total_is_set_once():
    reporter = Reporter(None, "task")
    reporter.advance()
    reporter.set_total(5)
    with pytest.raises(RuntimeError, match="already 5"):
        reporter.set_total(6)


def test_a_total_below_what_is_already_done_is_raised_to_it():
    """Units counted before the total was known (a total computed from an estimate, or late): the bar must not read
    past 100 %, so the total is at least what is done."""
    events = []
    reporter = Reporter(events.append, "task")
    reporter.advance(4)
    reporter.set_total(3)
    assert reporter.total == 4 and (events[-1].done, events[-1].total) == (4, 4)


def test_every_event_names_its_task():
    events = []
    with Reporter(events.append, "render scene-0001 CAM_FRONT", total=2, unit="frame") as reporter:
        reporter.advance()
    assert {(e.task, e.unit) for e in events} == {("render scene-0001 CAM_FRONT", "frame")} and events[-1].finished


def test_the_first_event_reports_nothing_done_with_an_empty_step():
    """A reporter's first event (the bar opens): nothing done, the total if known, and step "" (documented: "" when
    there is nothing new to say) that a callback may use as text."""
    events = []
    Reporter(events.append, "convert", total=3, unit="file")
    assert events == [Progress("convert", 0, 3, "file", "", False)]
