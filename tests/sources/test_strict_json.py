"""The strict JSON scan (`sources/strict_json.py`) against Python's json, which the devkit reads with: the same files
refused, at the same line and column, whatever the file size (small windows make a small file span many)."""

from __future__ import annotations

import json
import math

import pytest

from nuparquet.sources import strict_json
from nuparquet.sources.strict_json import strict_problem

# Strings holding what would be errors outside them (", inf", "nan:", ",]"), escaped quotes and backslashes, and the
# valid non-finite literals NaN, Infinity, -Infinity.
RECORDS = [{"token": f"t{i}", "text": 'say "hi", inf, nan: ok ,] \\ end \\', "values": [1.5, i, "NaN", math.nan,
            math.inf, -math.inf], "nested": {"a": None, "b": True, "c": [], "d": {}}} for i in range(40)]
TEXT = json.dumps(RECORDS, indent=4)

# (name, old, new, which occurrence): one edit, invalid for Python's json, read by DuckDB. (`True`, `None` and
# other words DuckDB refuses itself are not the scan's to find.)
INVALID = [
    ("trailing comma in an object", '"d": {}\n', '"d": {},\n', 7),
    ("trailing comma in a list", "-Infinity\n", "-Infinity,\n", 23),
    ("trailing comma with spaces", '"c": []', '"c": [1,   ]', 31),
    ("lowercase nan", '"a": null', '"a": nan', 17),
    ("uppercase NAN", '"a": null', '"a": NAN', 39),
    ("-NaN", '"a": null', '"a": -NaN', 5),
    ("inf in a list", "1.5,", "inf,", 12),
    ("-inf", "1.5,", "-inf,", 2),
    ("infinity", '"b": true', '"b": infinity', 28),
    ("the first record", '"a": null', '"a": nan', 0),
]


def _replace_nth(text: str, old: str, new: str, n: int) -> str:
    at = -1
    for _ in range(n + 1):
        at = text.index(old, at + 1)
    return text[:at] + new + text[at + len(old):]


@pytest.fixture(params=[None, (97, 13), (4096, 40)], ids=["one window", "97-byte windows", "4 kB windows"])
def windows(request, monkeypatch):
    if request.param is not None:
        monkeypatch.setattr(strict_json, "WINDOW_BYTES", request.param[0])
        monkeypatch.setattr(strict_json, "OVERLAP_BYTES", request.param[1])


@pytest.mark.parametrize("name, old, new, n", INVALID, ids=[case[0] for case in INVALID])
def test_invalid_json_is_found_at_pythons_position(tmp_path, windows, name, old, new, n):
    text = _replace_nth(TEXT, old, new, n)
    with pytest.raises(json.JSONDecodeError) as python:
        json.loads(text)
    path = tmp_path / "table.json"
    path.write_text(text)
    problem = strict_problem(path)
    assert problem is not None, name
    assert f"not valid JSON at line {python.value.lineno}, column {python.value.colno}: " in problem.message


def test_valid_json_with_lookalikes_in_strings_passes(tmp_path, windows):
    json.loads(TEXT)  # valid for Python's json
    path = tmp_path / "table.json"
    path.write_text(TEXT)
    assert strict_problem(path) is None


def test_the_column_counts_characters_not_bytes(tmp_path):
    text = '[{"name": "Zürich – 東京", "x": nan}]'
    with pytest.raises(json.JSONDecodeError) as python:
        json.loads(text)
    path = tmp_path / "table.json"
    path.write_text(text, encoding="utf-8")
    assert f"line 1, column {python.value.colno}:" in strict_problem(path).message


def test_a_bare_word_after_an_escaped_backslash_closing_a_string_is_found(tmp_path, windows):
    """`"a\\\\"` ends with an escaped backslash, so its last quote closes the string: a `nan` after it is outside."""
    text = json.dumps([{"p": "a\\", "q": 1}] * 30, indent=1).replace('"q": 1', '"q": nan', 1)
    with pytest.raises(json.JSONDecodeError) as python:
        json.loads(text)
    path = tmp_path / "table.json"
    path.write_text(text)
    assert f"line {python.value.lineno}, column {python.value.colno}:" in strict_problem(path).message
