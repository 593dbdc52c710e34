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


def test_resumed_units_are_counted_at_once_in_one_progress_step_named_resumed(tmp_path):
    """With --resume the units an earlier run finished are counted in one event whose step says "resumed" (the
    bar's text), then each unit run is counted under its name."""
    units = [WorkUnit("a", 1), WorkUnit("b", 2), WorkUnit("c", 3)]
    run_units(square_into_part, units[:2], parts_dir=tmp_path, options=EngineOptions(engine="serial"))
    events = []
    run_units(square_into_part, units, parts_dir=tmp_path, options=EngineOptions(engine="serial", resume=True),
              on_progress=events.append, label="scenes")
    assert [(e.done, e.total, e.step, e.finished) for e in events] == [
        (0, 3, "", False), (2, 3, "resumed", False), (3, 3, "c", False), (3, 3, "", True)]
    assert {(e.task, e.unit) for e in events} == {("scenes", "scene")}


@pytest.mark.parametrize("engine", ["serial", "process"])
def test_each_outcome_names_the_process_that_ran_its_unit(engine, tmp_path):
    """`worker`: the id of the process that ran the unit: this one on the serial engine, a worker on the pool."""
    outcomes = run_units(square_into_part, [WorkUnit("a", 1), WorkUnit("b", 2)], parts_dir=tmp_path,
                         options=EngineOptions(engine=engine, workers=1))
    workers = {o.worker for o in outcomes}
    if engine == "serial":
        assert workers == {os.getpid()}
    else:
        assert len(workers) == 1 and workers.isdisjoint({0, os.getpid()})  # one worker ran both


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


def test_an_unknown_name_of_the_engine_package_is_an_attribute_error_naming_it():
    import nuparquet.engine as engine

    with pytest.raises(AttributeError, match=r"^module 'nuparquet\.engine' has no attribute 'run_unit'$"):
        engine.run_unit  # noqa: B018 - a misspelt run_units
    assert not hasattr(engine, "backends_of_ray")


def test_default_workers_are_the_cores_this_process_may_run_on_else_every_core_else_one(monkeypatch):
    """The affinity mask (a container or `taskset` limited to 3 of 64 cores: 3 workers), where the system has one;
    else os.cpu_count(), and 1 when even that is unknown."""
    from nuparquet.engine.backends import default_workers

    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 3, 5}, raising=False)
    assert default_workers() == 3
    monkeypatch.delattr(os, "sched_getaffinity")  # macOS, Windows
    assert default_workers() == 64
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert default_workers() == 1


class _StopAtRayInit(Exception):
    pass


def _ray_init_arguments(monkeypatch, options: EngineOptions, tmp_path) -> dict:
    """The keyword arguments the Ray engine passes to `ray.init` for `options` (a stand-in `ray` module records
    them and stops the job there: no Ray is started)."""
    import types

    seen: dict = {}

    def init(**kwargs):
        seen.update(kwargs)
        raise _StopAtRayInit

    monkeypatch.setitem(sys.modules, "ray", types.SimpleNamespace(is_initialized=lambda: False, init=init))
    with pytest.raises(_StopAtRayInit):
        run_units(square_into_part, [WorkUnit("a", 1)], parts_dir=tmp_path, options=options)
    return seen


def test_ray_joins_the_cluster_of_ray_address_and_otherwise_starts_a_local_ray_of_workers_cpus(monkeypatch, tmp_path):
    """--ray-address joins that cluster (no local Ray, so no CPU count of ours); without it a local Ray of --workers
    CPUs is started, and --workers 0 (or none) means every core (here an affinity mask of 6 cores)."""
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(6)), raising=False)
    joined = _ray_init_arguments(monkeypatch, EngineOptions(engine="ray", ray_address="ray://head:10001"), tmp_path)
    assert joined["address"] == "ray://head:10001" and "num_cpus" not in joined
    assert joined["log_to_driver"] is False and joined["logging_level"] == "ERROR"  # Ray's own log: errors only
    local = _ray_init_arguments(monkeypatch, EngineOptions(engine="ray", workers=3), tmp_path)
    assert local["num_cpus"] == 3 and "address" not in local
    assert local["log_to_driver"] is False and local["logging_level"] == "ERROR"
    assert _ray_init_arguments(monkeypatch, EngineOptions(engine="ray", workers=0), tmp_path)["num_cpus"] == 6
    assert _ray_init_arguments(monkeypatch, EngineOptions(engine="ray"), tmp_path)["num_cpus"] == 6


def test_workers_0_means_every_core_and_any_other_count_is_kept():
    assert EngineOptions(workers=0).workers is None  # as if not given: every core
    assert EngineOptions(workers=1).workers == 1 and EngineOptions(workers=5).workers == 5
    with pytest.raises(UsageError, match="--workers must be 0 \\(every core\\) or more, got -1"):
        EngineOptions(workers=-1)


def test_a_failing_unit_on_the_process_pool_cancels_the_units_that_have_not_started(tmp_path):
    """One worker; "bad" fails at once, each other unit takes 0.6 s. The job stops with "bad": the pool runs at
    most the units already handed to its worker's queue (two or three) and cancels the rest, so the last unit,
    which would start 3 s after "bad" failed, never starts (no part folder) and nothing runs after the job
    returned."""
    from tasks import wait_or_fail

    units = [WorkUnit("bad", (0.0, True))] + [WorkUnit(f"wait-{i}", (0.6, False)) for i in range(1, 7)]
    with pytest.raises(UnitsFailed, match="bad: ValueError: unit bad failed on purpose"):
        run_units(wait_or_fail, units, parts_dir=tmp_path, options=EngineOptions(engine="process", workers=1))
    assert not (tmp_path / "wait-6").exists() and not (tmp_path / "wait-5").exists()
    assert not list(tmp_path.glob("*.done.json"))  # the units that did finish after the failure are not marked


def test_resume_reruns_a_unit_whose_marker_names_another_unit_or_records_an_error(tmp_path):
    """A marker is taken only for its own unit and only if it finished without error: b's marker copied from a's
    (a file copied by hand, an older layout), and c's recording an error, both run again."""
    import json
    import shutil

    run_units(square_into_part, [WorkUnit("a", 1)], parts_dir=tmp_path, options=EngineOptions(engine="serial"))
    shutil.copy(tmp_path / "a.done.json", tmp_path / "b.done.json")
    (tmp_path / "c.done.json").write_text(json.dumps({"name": "c", "value": 9, "error": "ValueError: boom",
                                                      "resumed": False, "seconds": 0.1, "peak_rss_mb": 1.0,
                                                      "worker": 1}))
    outcomes = run_units(square_into_part, [WorkUnit("a", 1), WorkUnit("b", 2), WorkUnit("c", 3)], parts_dir=tmp_path,
                         options=EngineOptions(engine="serial", resume=True))
    assert [(o.name, o.value, o.resumed) for o in outcomes] == [("a", 1, True), ("b", 4, False), ("c", 9, False)]
    assert (tmp_path / "b" / "value.txt").read_text() == "4" and (tmp_path / "c" / "value.txt").read_text() == "9"


def test_the_many_scene_summary_lists_the_dataset_the_callers_fields_the_scenes_written_and_those_failed(tmp_path):
    """`write_scene_files`' summary (what `render --all-scenes` and `export-mcap --all-scenes` leave beside their
    files): {"dataset", the caller's own fields (render: "channel"), "scenes": {scene: entry + settings}, "failed":
    {scene: error}}, and without extra fields just the three keys."""
    import json
    import re
    import types
    from dataclasses import dataclass

    from nuparquet.dataset import DatasetReference
    from nuparquet.engine.scene_files import SceneVerb, settings_digest, write_scene_files

    @dataclass
    class Options:
        scale: float = 0.5

    class Reference(DatasetReference):
        def open(self):  # a stand-in dataset: the toy verb only reads its root
            return types.SimpleNamespace(root=self.root)

    data = tmp_path / "data"
    data.mkdir()
    dataset = types.SimpleNamespace(root=data, is_remote=False, storage_options=None,
                                    reference=Reference(str(data.resolve())))
    verb = SceneVerb("tasks:scene_file", ".txt")
    out = tmp_path / "videos"
    with pytest.raises(UnitsFailed, match="bad-1: ValueError: scene bad-1 failed on purpose"):
        write_scene_files(dataset, ["s-1", "bad-1", "s-22"], out, verb, Options(),
                          EngineOptions(engine="serial", keep_going=True), summary_name="videos.json", file_key="file",
                          label="scenes", summary_fields={"channel": "CAM_FRONT"})
    summary = json.loads((out / "videos.json").read_text())
    assert sorted(summary) == ["channel", "dataset", "failed", "scenes"]
    assert summary["dataset"] == str(data.resolve()) and summary["channel"] == "CAM_FRONT"
    assert sorted(summary["scenes"]) == ["s-1", "s-22"]
    settings = summary["scenes"]["s-1"]["settings"]
    assert re.fullmatch("[0-9a-f]{12}", settings)
    assert summary["scenes"]["s-22"] == {"file": "s-22.txt", "frames": 4, "settings": settings}
    assert list(summary["failed"]) == ["bad-1"]
    assert summary["failed"]["bad-1"].startswith("ValueError: scene bad-1 failed on purpose (at tasks.py:")
    digest = settings_digest(str(data.resolve()), Options())  # the dataset and the whole options object
    assert settings == digest != settings_digest(str(data.resolve()), Options(scale=1.0))
    assert (out / "s-22.txt").read_text() == str(data.resolve())

    again = write_scene_files(dataset, ["s-3"], tmp_path / "other", verb, Options(),
                              EngineOptions(engine="serial"), summary_name="files.json", file_key="file",
                              label="scenes")
    summary = json.loads(again.summary.read_text())
    assert sorted(summary) == ["dataset", "failed", "scenes"] and summary["failed"] == {}
    assert summary["scenes"]["s-3"]["file"] == "s-3.txt" and again.written == ["s-3"]
