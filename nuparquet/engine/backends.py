"""The engines a job's units run on. Each is a generator of `(index, UnitOutcome)` in completion order over the
same `units.execute` call; closing the generator cancels what has not started and waits for (process pool) or
cancels (Ray) what is running, so nothing writes after the job returns.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from nuparquet.engine.options import RAY_INSTALL_HINT, EngineOptions
from nuparquet.engine.units import Task, UnitOutcome, WorkUnit, execute
from nuparquet.errors import UsageError

Jobs = Sequence[tuple[WorkUnit, Path]]
Outcomes = Iterator[tuple[int, UnitOutcome]]


def default_workers() -> int:
    """Every core this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def serial(task: Task, jobs: Jobs, options: EngineOptions, preload: Sequence[str] = ()) -> Outcomes:
    for index, (unit, part) in enumerate(jobs):
        yield index, execute(task, unit, str(part))


def process_pool(task: Task, jobs: Jobs, options: EngineOptions, preload: Sequence[str] = ()) -> Outcomes:
    """`preload`: modules that import no thread pool (the point reader: numpy, pyarrow); given, workers fork from a
    forkserver that imported them once instead of each starting an interpreter (~0.3 s a worker)."""
    workers = min(options.workers or default_workers(), len(jobs))
    # spawn, not fork: the parent has polars' thread pool running, and a forked child may inherit a held lock. A
    # forkserver is a fresh process too; it only imports `preload`.
    context = multiprocessing.get_context("forkserver" if preload else "spawn")
    if preload:
        context.set_forkserver_preload(["nuparquet.engine.units", *preload])
    executor = ProcessPoolExecutor(max_workers=workers, mp_context=context)
    try:
        futures = {executor.submit(execute, task, unit, str(part)): index for index, (unit, part) in enumerate(jobs)}
        for future in as_completed(futures):
            index = futures[future]
            try:
                yield index, future.result()
            except Exception as exc:  # noqa: BLE001 - the worker process died (killed, out of memory)
                yield index, UnitOutcome(jobs[index][0].name, error=f"worker process died: {exc!r}")
    finally:
        executor.shutdown(wait=True, cancel_futures=True)


def import_ray():
    """The `ray` module, or a UsageError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise UsageError(f"--engine ray needs Ray, which is not installed: {RAY_INSTALL_HINT}") from None
    return ray


def ray_tasks(task: Task, jobs: Jobs, options: EngineOptions, preload: Sequence[str] = ()) -> Outcomes:
    """Ray tasks of one CPU each, on the Ray this process is already connected to, else the cluster of
    `options.ray_address`, else a local Ray of `options.workers` CPUs (shut down again at the end)."""
    ray = import_ray()
    started = False
    if not ray.is_initialized():
        if options.ray_address is not None:
            ray.init(address=options.ray_address, logging_level="ERROR", log_to_driver=False)
        else:
            ray.init(num_cpus=options.workers or default_workers(), include_dashboard=False,
                     logging_level="ERROR", log_to_driver=False)
        started = True
    pending: dict = {}
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(execute)
        pending = {remote.remote(task, unit, str(part)): index for index, (unit, part) in enumerate(jobs)}
        while pending:
            (ref,), _ = ray.wait(list(pending), num_returns=1)
            index = pending.pop(ref)
            try:
                outcome = ray.get(ref)
            except Exception as exc:  # noqa: BLE001 - the task's worker died, or Ray could not run it
                outcome = UnitOutcome(jobs[index][0].name, error=f"Ray task failed: {type(exc).__name__}: {exc}")
            yield index, outcome
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


BACKENDS = {"serial": serial, "process": process_pool, "ray": ray_tasks}
