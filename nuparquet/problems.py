"""Integrity problems found in an input dataset: each names the file, the record index and the token."""

from __future__ import annotations

import re
from dataclasses import dataclass

from nuparquet.errors import InputError

MAX_REPORTED = 50  # problems printed per run; the rest are counted
ECHO_CHARS = 100  # a value quoted in a message is cut to about this many characters

_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def echo(value, limit: int = ECHO_CHARS, *, quote: bool = True) -> str:
    """`value` as quoted in a message: its repr (`quote=False`: the text as it is, e.g. a JSON fragment), control
    characters escaped, cut to about `limit` characters (a 4 MB string in the data must not fill the terminal; an
    escape sequence must not reach it raw)."""
    text = repr(value) if isinstance(value, str) and quote else str(value)
    text = _CONTROL.sub(lambda m: m.group(0).encode("unicode_escape").decode("ascii"), text)
    length = len(value) if isinstance(value, str) else len(text)
    return text if len(text) <= limit else f"{text[:limit]}... ({length:,} characters)"


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
        # control characters from the data never reach the terminal raw, whatever the message quotes
        text = _CONTROL.sub(lambda m: m.group(0).encode("unicode_escape").decode("ascii"), f"{where}: {self.message}")
        return f"{'warning: ' if self.warning else ''}{text}"


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
