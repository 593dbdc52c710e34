"""The engine's contract, with a toy task: outcomes in unit order, part folders, failures named by unit,
--keep-going, --resume from completion markers, Ray asked for without Ray installed, and one Ray job (a session of
its own) stopped by a failing unit."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from nuparquet.cli.main import main
from nuparquet.engine import EngineOptions, UnitsFailed, WorkUnit, move_parts, raise_failures, run_units
from nuparquet.errors import UsageError

from tasks import square_into_part


@pytest.mark.parametrize("engine", ["serial", "process"])
def test_outcomes_come_back_in_unit_order_with_each_units_part_files(engine, tmp_path):
    values = [7, 3, 11, 0, 5]
    units = [WorkUnit(f"scene-{i}", v) for i, v in enumerate(values)]
    outcomes = run_units(square_into_part, units, parts_dir=tmp_path, options=EngineOptions(engine=engine, workers=2))
    assert [o.name for o in outcomes] == [u.name for u in units]
    assert [o.value for o in outcomes] == [v * v for v in values]
    for unit, value in zip(units, values):
        assert (tmp_path / unit.name / "value.txt").read_text() == str(value * value)
    assert all(o.ok and not o.resumed and o.peak_rss_mb > 0 for o in outcomes)


@pytest.mark.parametrize("engine", ["serial", "process"])
def test_a_raising_unit_stops_the_job_named_with_its_error(engine, tmp_path):
    units = [WorkUnit("a", 1), WorkUnit("bad", -2), WorkUnit("c", 3)]
    with pytest.raises(UnitsFailed) as failed:
        run_units(square_into_part, units, parts_dir=tmp_path, options=EngineOptions(engine=engine, workers=1))
    message = str(failed.value)
    assert "bad: ValueError: negative input -2 (at tasks.py:" in message and "--keep-going" in message
    assert [f.name for f in failed.value.failures] == ["bad"]
    assert not (tmp_path / "bad").exists()  # the failed unit's part folder is removed


def test_keep_going_finishes_the_other_units(tmp_path):
    units = [WorkUnit("a", 1), WorkUnit("bad", -2), WorkUnit("c", 3)]
    outcomes = run_units(square_into_part, units, parts_dir=tmp_path,
                         options=EngineOptions(engine="process", workers=2, keep_going=True))
    assert [(o.name, o.value, o.ok) for o in outcomes] == [("a", 1, True), ("bad", None, False), ("c", 9, True)]
    assert (tmp_path / "c" / "value.txt").read_text() == "9"


def test_resume_skips_completed_units_and_reruns_the_rest(tmp_path):
    units = [WorkUnit("a", 1), WorkUnit("bad", -2), WorkUnit("c", 3)]
    with pytest.raises(UnitsFailed):
        run_units(square_into_part, units, parts_dir=tmp_path, options=EngineOptions(engine="serial"))
    # The serial engine stopped at "bad": "a" finished (marked complete), "c" never ran.
    (tmp_path / "a" / "value.txt").write_text("kept")  # a rerun of "a" would overwrite this
    fixed = [WorkUnit("a", 1), WorkUnit("bad", 2), WorkUnit("c", 3)]
    outcomes = run_units(square_into_part, fixed, parts_dir=tmp_path, options=EngineOptions(engine="serial", resume=True))
    assert [(o.name, o.value, o.resumed) for o in outcomes] == [("a", 1, True), ("bad", 4, False), ("c", 9, False)]
    assert (tmp_path / "a" / "value.txt").read_text() == "kept"
    # Without --resume every unit runs again.
    outcomes = run_units(square_into_part, fixed, parts_dir=tmp_path, options=EngineOptions(engine="serial"))
    assert not any(o.resumed for o in outcomes) and (tmp_path / "a" / "value.txt").read_text() == "1"


def test_a_failed_rerun_without_resume_leaves_no_unit_marked_done_without_its_parts(tmp_path):
    """Run 1 finishes a and c (markers written, parts not yet committed). Run 2, without --resume, starts afresh:
    it clears every unit, then stops at its first unit, which fails, so a and c never run again. Run 3 with
    --resume must not take a and c as done: their markers went with their parts, so they run again."""
    run_units(square_into_part, [WorkUnit("a", 1), WorkUnit("c", 3)], parts_dir=tmp_path,
              options=EngineOptions(engine="serial"))
    assert (tmp_path / "a.done.json").exists() and (tmp_path / "c" / "value.txt").exists()
    with pytest.raises(UnitsFailed):
        run_units(square_into_part, [WorkUnit("bad", -1), WorkUnit("a", 1), WorkUnit("c", 3)], parts_dir=tmp_path,
                  options=EngineOptions(engine="serial"))
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # cleared: nothing half-done is left to resume
    outcomes = run_units(square_into_part, [WorkUnit("bad", 2), WorkUnit("a", 1), WorkUnit("c", 3)],
                         parts_dir=tmp_path, options=EngineOptions(engine="serial", resume=True))
    assert [(o.name, o.value, o.resumed) for o in outcomes] == [("bad", 4, False), ("a", 1, False), ("c", 9, False)]
    for outcome in outcomes:  # every unit reported done has its part files
        assert (tmp_path / outcome.name / "value.txt").read_text() == str(outcome.value)


def test_resume_takes_units_the_caller_committed(tmp_path):
    units = [WorkUnit("a", 1), WorkUnit("b", 2)]
    outcomes = run_units(square_into_part, units, parts_dir=tmp_path, committed={"a": 1},
                         options=EngineOptions(engine="serial", resume=True))
    assert [(o.value, o.resumed) for o in outcomes] == [(1, True), (4, False)]
    assert not (tmp_path / "a").exists()


def test_unit_names_that_are_not_file_names_stay_inside_the_parts_folder(tmp_path):
    parts = tmp_path / "parts"
    outcomes = run_units(square_into_part, [WorkUnit("../escape", 2), WorkUnit(".hidden/x", 3)], parts_dir=parts,
                         options=EngineOptions(engine="serial"))
    assert [o.value for o in outcomes] == [4, 9]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["parts"]
    assert len([p for p in parts.iterdir() if p.is_dir()]) == 2


def test_duplicate_unit_names_are_refused(tmp_path):
    with pytest.raises(UsageError, match="unique"):
        run_units(square_into_part, [WorkUnit("a", 1), WorkUnit("a", 2)], parts_dir=tmp_path)


def test_ray_engine_without_ray_says_how_to_install_it(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    with pytest.raises(UsageError, match=r"pip install 'nuparquet\[ray\]'"):
        run_units(square_into_part, [WorkUnit("a", 1)], parts_dir=tmp_path, options=EngineOptions(engine="ray"))
    assert main(["render", str(tmp_path), "--all-scenes", "--out-dir", str(tmp_path / "v"), "--engine", "ray"]) == 2
    assert "nuparquet[ray]" in capsys.readouterr().err


@pytest.mark.xdist_group("ray")  # one Ray session at a time (make test: --dist loadgroup)
def test_on_ray_a_failing_unit_stops_the_job_named_with_its_error_and_workers_print_nothing_to_the_driver(
        tmp_path, capfd, monkeypatch):
    """One local Ray, started (and stopped) by the engine itself through `--ray-address local` (Ray's address for "a
    new local instance"): "bad" fails after 1.5 s while "slow" is running and two more units are pending or running.
    The job stops with UnitsFailed naming "bad" and its own ValueError (what is left is cancelled, ref by ref), and
    nothing a unit printed in its worker reaches the driver's output (Ray joined with log_to_driver=False: "slow"
    printed 1.5 s before the job ended, time enough for Ray to forward it)."""
    from tasks import wait_or_fail

    # Ray's workers import the task by its module name: they find `tasks` through the environment the engine's
    # ray.init hands to the local Ray it starts
    here = str(Path(__file__).resolve().parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [here, os.environ.get("PYTHONPATH")])))

    units = [WorkUnit("slow", (30.0, False)), WorkUnit("bad", (1.5, True)), WorkUnit("pending-1", (30.0, False)),
             WorkUnit("pending-2", (30.0, False))]
    with pytest.raises(UnitsFailed) as failed:
        run_units(wait_or_fail, units, parts_dir=tmp_path, options=EngineOptions(engine="ray", ray_address="local"))
    assert [f.name for f in failed.value.failures] == ["bad"]
    assert "bad: ValueError: unit bad failed on purpose" in str(failed.value)
    out, err = capfd.readouterr()
    assert "printed by unit" not in out + err


def test_ray_address_without_the_ray_engine_is_a_usage_error(tmp_path):
    with pytest.raises(UsageError, match="--ray-address needs --engine ray"):
        run_units(square_into_part, [WorkUnit("a", 1)], parts_dir=tmp_path,
                  options=EngineOptions(engine="process", ray_address="auto"))


@pytest.mark.parametrize("engine", ["serial", "process"])
def test_parts_are_committed_in_unit_order_whatever_order_units_finished(engine, tmp_path):
    # Units of decreasing size finish in another order on the pool; the commit follows the unit list.
    values = [9, 4, 7, 1, 8]
    units = [WorkUnit(f"scene-{v}", v) for v in values]
    outcomes = run_units(square_into_part, units, parts_dir=tmp_path / "parts",
                         options=EngineOptions(engine=engine, workers=2))
    committed = move_parts(outcomes, tmp_path / "parts", tmp_path / "dataset")
    assert [p.name for p in committed] == [f"{i:05d}-value.txt" for i in range(len(values))]
    assert [p.read_text() for p in committed] == [str(v * v) for v in values]
    assert not any((tmp_path / "parts").iterdir())  # part folders and markers gone


def test_a_failed_unit_leaves_no_part_in_the_commit(tmp_path):
    units = [WorkUnit("a", 2), WorkUnit("bad", -1), WorkUnit("c", 3)]
    outcomes = run_units(square_into_part, units, parts_dir=tmp_path / "parts",
                         options=EngineOptions(engine="serial", keep_going=True))
    committed = move_parts(outcomes, tmp_path / "parts", tmp_path / "dataset")
    assert [(p.name, p.read_text()) for p in committed] == [("00000-value.txt", "4"), ("00002-value.txt", "9")]
    with pytest.raises(UnitsFailed, match="bad: ValueError") as failed:
        raise_failures(outcomes)
    # after --keep-going the others did finish and were committed: the message must not say otherwise
    assert "1 unit(s) failed; the other units finished:" in str(failed.value)
    assert "nothing was committed" not in str(failed.value)


def test_parts_and_output_folders_are_made_with_their_parents_and_an_existing_output_folder_is_kept(tmp_path):
    parts, dest = tmp_path / "deep" / "parts", tmp_path / "out" / "nested" / "dataset"
    outcomes = run_units(square_into_part, [WorkUnit("a", 2)], parts_dir=parts, options=EngineOptions(engine="serial"))
    assert [p.read_text() for p in move_parts(outcomes, parts, dest)] == ["4"]
    again = run_units(square_into_part, [WorkUnit("b", 3)], parts_dir=parts, options=EngineOptions(engine="serial"))
    assert [p.name for p in move_parts(again, parts, dest)] == ["00000-value.txt"]  # into the existing folder
    assert (dest / "00000-value.txt").read_text() == "9"


def test_peak_memory_is_reported_in_mb_to_one_decimal(tmp_path):
    outcome, = run_units(square_into_part, [WorkUnit("a", 2)], parts_dir=tmp_path, options=EngineOptions(engine="serial"))
    assert type(outcome.peak_rss_mb) is float and outcome.peak_rss_mb == round(outcome.peak_rss_mb, 1) > 1.0


@pytest.mark.parametrize("preload", [(), ("tasks",)])
def test_process_pool_workers_start_fresh_without_the_parents_state(tmp_path, preload):
    """Workers are spawned (or forked from a forkserver that only imported `preload`), never forked from the
    parent, whose thread pools may hold a lock: a module global the parent changed is back to its initial value
    in the workers."""
    import tasks

    tasks.STATE["in_parent_only"] = True
    try:
        outcomes = run_units(tasks.parent_state_seen, [WorkUnit("a", 0), WorkUnit("b", 0)], parts_dir=tmp_path,
                             options=EngineOptions(engine="process", workers=2), preload=preload)
    finally:
        tasks.STATE.clear()
    assert [(o.ok, o.value) for o in outcomes] == [(True, False), (True, False)]
