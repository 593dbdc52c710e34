"""Refuse JSON that DuckDB's lenient `read_json` would accept: a trailing comma, `nan`/`inf`/`True`/`None`
and other bare words outside strings. (Python's json, which the devkit uses, rejects them; NaN, Infinity and
-Infinity are accepted, as Python's json accepts them.)

A regular-expression scan over the memory-mapped file finds candidates; only a file with a candidate — which may
still sit inside a string — is parsed by Python's json to decide, and its JSONDecodeError gives the position.
The scan runs at ~30 MB/s (commas and colons are everywhere in JSON, so the pattern is tried at most bytes): it
would double a trainval conversion, so files over `MAX_STRICT_BYTES` (trainval's sample_data, sample_annotation
and ego_pose) are left to DuckDB's reader. A faster scan is an open item of the real-derived-datasets issue.
"""

from __future__ import annotations

import json
import mmap
import re
from pathlib import Path

from nuparquet.problems import Problem

_TRAILING_COMMA = rb",\s*[\]}]"
_BARE_WORD = rb"[:\[,]\s*(?!true\b|false\b|null\b|NaN\b|Infinity\b|-Infinity\b)-?[A-Za-z_]"
_CANDIDATE = re.compile(_TRAILING_COMMA + rb"|" + _BARE_WORD)
MAX_STRICT_BYTES = 256 * 2**20


def strict_problem(path: Path) -> Problem | None:
    """A problem naming the file and the position of the first invalid JSON, or None (also for files over
    MAX_STRICT_BYTES, not scanned)."""
    if path.stat().st_size > MAX_STRICT_BYTES:
        return None
    with path.open("rb") as f:
        try:
            data = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except ValueError:  # an empty file: the reader names that itself
            return None
        with data:
            if _CANDIDATE.search(data) is None:
                return None
            try:
                json.loads(data[:].decode("utf-8", errors="replace"))
            except json.JSONDecodeError as exc:
                return Problem(path.name, f"not valid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}")
    return None
