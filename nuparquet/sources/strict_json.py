"""Refuse JSON that DuckDB's lenient `read_json` would accept but Python's json (and so the devkit) refuses: a
trailing comma inside an object or array, and the bare words `nan`, `inf`, `infinity` in any case (and `-NaN`).
`NaN`, `Infinity` and `-Infinity` are valid here, as in Python's json.

Every file is scanned, whatever its size, in windows of `WINDOW_BYTES` (memory stays bounded), in two steps:
- a prefilter at C speed over each window, on a copy without whitespace, lowered, `}` written `]`: no `,]` means no
  trailing comma; the bare words counted case-insensitively (`nan`, `inf`) equal to the valid spellings counted in
  the window itself (`NaN`, `Infinity`), and no `-nan`, mean no bare word;
- only a window the prefilter flags is searched with positions, and each candidate is kept only if it lies outside
  a JSON string (the parity of unescaped quotes before it). Text inside strings ("temperature: inf") flags a window
  but is never an error.
The first error is reported at the position Python's json reports (a trailing comma at the bracket that follows it,
a bare word at its first character), as line and column.
"""

from __future__ import annotations

import mmap
import re
from pathlib import Path

from nuparquet.problems import Problem

WINDOW_BYTES = 16 * 2**20
# A window is read with this much of the next one, so a pattern straddling the boundary (a comma, whitespace, a
# bracket; a bare word) is seen whole; a run of whitespace longer than this between a comma and a bracket is not.
OVERLAP_BYTES = 64 * 2**10

_CANDIDATE = re.compile(rb",[ \t\r\n]*([\]}])|[:\[,][ \t\r\n]*(-?[A-Za-z_][A-Za-z0-9_]*)")
_WORD = re.compile(rb"-?[A-Za-z_][A-Za-z0-9_]*")
_VALID_WORDS = {b"true", b"false", b"null", b"NaN", b"Infinity", b"-Infinity"}
_SQUEEZE = bytes.maketrans(b"ABCDEFGHIJKLMNOPQRSTUVWXYZ}", b"abcdefghijklmnopqrstuvwxyz]")


def strict_problem(path: Path) -> Problem | None:
    """A problem naming the file and the line and column of the first JSON error DuckDB would let through, or None."""
    with path.open("rb") as f:
        try:
            data = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except ValueError:  # an empty file: the reader names that itself
            return None
        with data:
            pos, what = _first_error(data)
            if pos is None:
                return None
            line, column = _line_column(data, pos)
    return Problem(path.name, f"not valid JSON at line {line}, column {column}: {what}")


def _first_error(data: mmap.mmap) -> tuple[int | None, str]:
    """The byte position of the first error and what it is, or (None, "")."""
    quotes_before, counted_to = 0, 0  # unescaped quotes before `counted_to`, counted only up to a flagged window
    for start in range(0, len(data), WINDOW_BYTES):
        window = data[start:start + WINDOW_BYTES + OVERLAP_BYTES]
        if not _flagged(window):
            continue
        quotes_before += _unescaped_quotes(data, counted_to, start)
        counted_to = start
        found = _error_in_window(data, window, start, quotes_before)
        if found[0] is not None:
            return found
    return None, ""


def _flagged(window: bytes) -> bool:
    """Whether a window may hold a trailing comma or a bare word (no false negatives)."""
    # One copy without whitespace, lowered and with `}` as `]`: a trailing comma is then `,]`, `-NaN` is `-nan`.
    squeezed = window.translate(_SQUEEZE, b" \t\r\n")
    if b",]" in squeezed or b"-nan" in squeezed:
        return True
    return squeezed.count(b"nan") + squeezed.count(b"inf") != window.count(b"NaN") + window.count(b"Infinity")


def _error_in_window(data: mmap.mmap, window: bytes, start: int, quotes_before: int) -> tuple[int | None, str]:
    """The first candidate of the window (starting before the next window) that lies outside every string."""
    end = min(WINDOW_BYTES, len(window))
    counted, quotes = 0, quotes_before
    for match in _CANDIDATE.finditer(window, 0, len(window)):
        if match.start() >= end:
            break
        pos = match.start(1) if match.group(1) is not None else match.start(2)
        word = None if match.group(2) is None else _WORD.match(data, start + pos).group(0)  # whole, past the window
        if word is not None and word in _VALID_WORDS:
            continue
        quotes += _unescaped_quotes(data, start + counted, start + match.start())
        counted = match.start()
        if quotes % 2:  # inside a string
            continue
        if word is None:
            return start + pos, f"a trailing comma before {match.group(1).decode()!r}"
        shown = word[:40].decode("ascii", errors="replace")
        return start + pos, f"the bare word {shown!r} (JSON allows only NaN, Infinity and -Infinity)"
    return None, ""


def _unescaped_quotes(data: mmap.mmap, begin: int, end: int) -> int:
    """The number of `"` in data[begin:end] that are not escaped by an odd run of backslashes."""
    if end <= begin:
        return 0
    part = data[begin:end]
    quotes = part.count(b'"')
    at = part.find(b'\\"')
    while at != -1:
        run, i = 0, begin + at
        while i >= 0 and data[i] == 0x5C:  # backslashes before the quote, possibly before `begin`
            run, i = run + 1, i - 1
        quotes -= run % 2
        at = part.find(b'\\"', at + 2)
    return quotes


def _line_column(data: mmap.mmap, pos: int) -> tuple[int, int]:
    """1-based line and column (in characters, as Python's json counts them) of byte `pos`."""
    lines, line_start = 0, 0
    for start in range(0, pos, WINDOW_BYTES):
        part = data[start:min(pos, start + WINDOW_BYTES)]
        lines += part.count(b"\n")
        last = part.rfind(b"\n")
        if last != -1:
            line_start = start + last + 1
    return lines + 1, len(data[line_start:pos].decode("utf-8", errors="replace")) + 1
