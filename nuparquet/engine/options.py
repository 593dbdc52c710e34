"""How a job over many scenes runs: the engine, its workers, and what to do about failures, declared once.

Light on purpose (no ray, no multiprocessing): the CLI builds its flags from these without loading an engine.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nuparquet.errors import UsageError
from nuparquet.options import option

ENGINES = ("process", "ray", "serial")
RAY_INSTALL_HINT = "pip install 'nuparquet[ray]' (or pip install 'ray>=2.9')"


@dataclass
class EngineOptions:
    """Where the work units (scenes) of a job run, and how failures end it."""

    engine: Literal["process", "ray", "serial"] = option(
        "process", help="where scenes run: 'process' (a pool of local processes, default), 'ray' (Ray tasks: "
        "a local Ray started with --workers CPUs, or the cluster of --ray-address; the dataset, the dataroot and "
        "the output must be on storage every node sees) or 'serial' (one at a time in this process). The outputs "
        "are the same byte for byte")
    workers: int | None = option(
        None, metavar="N", help="processes (or local Ray CPUs) to use; default (or 0): every core of this machine. "
        "The outputs are the same whatever N")
    ray_address: str | None = option(
        None, metavar="ADDRESS", help="join this Ray cluster (e.g. 'auto' on a cluster node, or "
        "ray://head:10001) instead of starting a local Ray; needs --engine ray")
    keep_going: bool = option(
        False, help="when a scene fails, finish the others (their outputs are written), then exit 1 listing the "
        "failed scenes; by default the first failure stops the job and nothing is committed")
    resume: bool = option(
        False, help="skip scenes whose outputs are complete from an earlier run with the same options (committed, "
        "or finished by a run that stopped on a failure)")

    def __post_init__(self) -> None:
        if self.engine not in ENGINES:
            raise UsageError(f"--engine must be one of {', '.join(ENGINES)}, got {self.engine!r}")
        if self.workers is not None and self.workers < 0:
            raise UsageError(f"--workers must be 0 (every core) or more, got {self.workers}")
        if self.workers == 0:
            self.workers = None  # every core
        if self.ray_address is not None and self.engine != "ray":
            raise UsageError("--ray-address needs --engine ray")
