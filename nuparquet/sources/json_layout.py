"""The whitespace of a JSON array file, so that `export-json` writes it back byte for byte.

The readers keep every value; this keeps the layout. nuScenes' tables are Python's `json.dump(records, f, indent=2)`
(attribute, log, map and visibility: `indent=0`), the generator writes `indent=0`, other tools a compact array
(`indent=None`: one line, ", " and ": "), and `export-json` itself one record a line. `detect` names the layout of a
file from its first record (re-serialised, it must give the same text) and its last bytes; `write_array` writes
records in it. A file in any other layout (hand-edited, other separators, a first record over `HEAD_BYTES`) has no
detected layout and is written one record a line: equal value for value, not byte for byte.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path
from typing import TextIO

HEAD_BYTES = 1 << 20  # enough for the first record of any nuScenes table
LINES = "lines"  # export-json's own layout: "[", one record a line (compact), "]"
_INDENTED = re.compile(r"\[\n( *)\{")


def _dumps(record, indent: int | str | None) -> str:
    if isinstance(indent, int):
        return json.dumps(record, indent=indent).replace("\n", "\n" + " " * indent)  # one level deeper than the array
    return json.dumps(record)


def detect(path: Path) -> dict | None:
    """{"indent": None | int | "lines", "newline": bool} for a JSON array of records written by Python's json in one
    of the layouts above (checked on the first record), else None."""
    with path.open("rb") as f:
        head = f.read(HEAD_BYTES).decode("utf-8", errors="replace")
        f.seek(max(f.seek(0, 2) - 16, 0))
        tail = f.read().decode("utf-8", errors="replace")
    newline = tail.endswith("]\n")
    if head.startswith("[]"):
        return {"indent": None, "newline": newline} if tail in ("[]", "[]\n") else None
    indented = _INDENTED.match(head)
    if head.startswith("[{"):
        candidates, start = [None], 1
    elif head.startswith('[\n{"'):
        candidates, start = [LINES], 2
    elif indented:
        candidates, start = [len(indented.group(1))], indented.end() - 1
    else:
        return None
    try:
        first, end = json.JSONDecoder().raw_decode(head, start)
    except json.JSONDecodeError:  # a first record longer than the head, or not JSON at all
        return None
    for indent in candidates:
        layout = {"indent": indent, "newline": newline}
        _, separator, closing, _ = delimiters(layout)
        after = head[end:end + len(separator)]
        if (_dumps(first, indent) == head[start:end] and tail.endswith("}" + closing)
                and (separator.startswith(after) or closing.startswith(after))):
            return layout
    return None


def delimiters(layout: dict | None) -> tuple[str, str, str, str]:
    """(before the first record, between records, after the last, the whole of an empty array) in `layout`
    (`detect`; None: one record a line), the final newline included."""
    indent = LINES if layout is None else layout["indent"]
    end = "\n" if layout is None or layout["newline"] else ""
    if indent is None:
        return "[", ", ", "]" + end, "[]" + end
    if indent == LINES:
        return "[\n", ",\n", "\n]" + end, "[\n]" + end
    prefix = " " * indent
    return "[\n" + prefix, ",\n" + prefix, "\n]" + end, "[]" + end


def dumps(record: dict, layout: dict | None) -> str:
    """One record of an array in `layout`."""
    return _dumps(record, LINES if layout is None else layout["indent"])


def write_array(out: TextIO, records: Iterable[dict], layout: dict | None) -> None:
    """`records` as a JSON array in `layout`."""
    opening, separator, closing, empty = delimiters(layout)
    first = True
    for record in records:
        out.write(opening if first else separator)
        out.write(dumps(record, layout))
        first = False
    out.write(empty if first else closing)
