"""Integrity problems found in an input dataset: each names the file, the record index and the token."""

from __future__ import annotations

from dataclasses import dataclass

from nuparquet.errors import InputError

MAX_REPORTED = 50  # problems printed per run; the rest are counted


@dataclass(frozen=True)
class Problem:
    file: str  # e.g. "sample_data.json"
    message: str
    index: int | None = None  # 0-based record index in the JSON array
    token: str | None = None
    omitted: int = 0  # > 0: a summary standing for this many further problems of the same check
    warning: bool = False  # accepted as the devkit accepts it, but worth knowing (a near-unit quaternion)

    def __str__(self) -> str:
        where = self.file if self.index is None else f"{self.file}[{self.index}]"
        if self.token is not None:
            where += f" token={self.token}"
        return f"{'warning: ' if self.warning else ''}{where}: {self.message}"


def split_warnings(problems: list[Problem]) -> tuple[list[Problem], list[Problem]]:
    """(errors, warnings)."""
    return [p for p in problems if not p.warning], [p for p in problems if p.warning]


def count_problems(problems: list[Problem]) -> int:
    return sum(p.omitted or 1 for p in problems)


def format_problems(problems: list[Problem], limit: int = MAX_REPORTED) -> str:
    """The first `limit` problems, then how many were not shown, then each check's summary of omissions."""
    listed = [p for p in problems if not p.omitted]
    lines = [str(p) for p in listed[:limit]]
    if len(listed) > limit:
        lines.append(f"... and {len(listed) - limit} more problems not shown")
    lines += [f"{p.file}: ... {p.message}" for p in problems if p.omitted]
    return "\n".join(lines)


class ProblemsFound(InputError):
    """The input has integrity problems; `problems` holds them all."""

    def __init__(self, problems: list[Problem]):
        self.problems = problems
        n = count_problems(problems)
        super().__init__(f"{n} problem{'s' if n != 1 else ''} in the input:\n{format_problems(problems)}")
