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

    def __str__(self) -> str:
        where = self.file if self.index is None else f"{self.file}[{self.index}]"
        if self.token is not None:
            where += f" token={self.token}"
        return f"{where}: {self.message}"


def format_problems(problems: list[Problem], limit: int = MAX_REPORTED) -> str:
    lines = [str(p) for p in problems[:limit]]
    if len(problems) > limit:
        lines.append(f"... and {len(problems) - limit} more problems ({len(problems)} in all)")
    return "\n".join(lines)


class ProblemsFound(InputError):
    """The input has integrity problems; `problems` holds them all."""

    def __init__(self, problems: list[Problem]):
        self.problems = problems
        n = len(problems)
        super().__init__(f"{n} problem{'s' if n != 1 else ''} in the input:\n{format_problems(problems)}")
