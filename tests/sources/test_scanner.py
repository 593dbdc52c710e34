"""The table reader's one-pass scanner (`sources/table_scan.py` over `sources/json_scan.py`) against Python's json,
which the devkit reads with: the same files refused, at the same line and column; the same values kept, whatever
the window size (small windows make a small file span many, and grow the streams from their smallest size).
Every edge of the fuzz (tests/fuzz) is here on its own: unicode and control characters, long strings, duplicate
keys, a BOM, trailing garbage, deep nesting, an empty file, `{}` or `null` as a table, truncation, junk bytes."""

from __future__ import annotations

import json
import math
import random

import pytest

from nuparquet.schemas import Field, Schema
from nuparquet.sources import json_scan, table_scan
from nuparquet.sources.tables import read_table

# One optional string field; everything else is an extra field, kept as its raw JSON text.
SCHEMA = Schema("table", "table", 1, "", (Field("token", "string", required=False, nullable=True),), "table.json")

# Strings holding what would be errors outside them (", inf", "nan:", ",]"), escaped quotes and backslashes, and the
# valid non-finite literals NaN, Infinity, -Infinity.
RECORDS = [{"token": f"t{i}", "text": 'say "hi", inf, nan: ok ,] \\ end \\', "values": [1.5, i, "NaN", math.nan,
            math.inf, -math.inf], "nested": {"a": None, "b": True, "c": [], "d": {}}} for i in range(40)]
TEXT = json.dumps(RECORDS, indent=4)

# (name, old, new, which occurrence): one edit, invalid for Python's json, read by lenient parsers.
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
    ("a leading zero", '"values": [\n            1.5', '"values": [\n            01.5', 3),
    ("a dot without digits", "1.5,", "1.,", 9),
    ("an exponent without digits", "1.5,", "1.5e,", 9),
    ("a plus sign", "1.5,", "+1.5,", 9),
    ("a single quote", '"a": null', "\"a\": 'x'", 9),
    ("True", '"b": true', '"b": True', 9),
    ("a bad escape", "\\\\ end", "\\x end", 9),
    ("a short unicode escape", "\\\\ end", "\\u12 end", 9),
    ("a missing colon", '"a": null', '"a" null', 9),
    ("a missing comma between records", '},\n    {', '}\n    {', 9),
    ("an unquoted key", '"a": null', 'a: null', 9),
    ("a raw tab in a string", "say", "s\ty", 9),
    ("more data after the array", "\n]", "\n]]", 0),
    ("a trailing comma after the last record", "}\n]", "},\n]", 0),
]


def _replace_nth(text: str, old: str, new: str, n: int) -> str:
    at = -1
    for _ in range(n + 1):
        at = text.index(old, at + 1)
    return text[:at] + new + text[at + len(old):]


@pytest.fixture(params=[None, 97, 4096], ids=["one window", "97-byte windows", "4 kB windows"])
def windows(request, monkeypatch):
    if request.param is not None:
        monkeypatch.setattr(table_scan, "WINDOW_BYTES", request.param)


def _read(tmp_path, text: str | bytes):
    path = tmp_path / "table.json"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
    return read_table(path, SCHEMA)


def _as_records(source) -> list[dict]:
    """The records a read table holds, rebuilt as Python's json would give them."""
    table = source.table
    rows = table.to_pylist()
    layouts = source.layouts or [source.key_order]
    out = []
    for row in rows:
        keys = layouts[row.get("_layout") or 0]
        out.append({k: (json.loads(row[k]) if k in source.json_fields else row[k]) for k in keys})
    return out


@pytest.mark.parametrize("name, old, new, n", INVALID, ids=[case[0] for case in INVALID])
def test_invalid_json_is_refused_at_pythons_position(tmp_path, windows, name, old, new, n):
    text = _replace_nth(TEXT, old, new, n)
    with pytest.raises(json.JSONDecodeError) as python:
        json.loads(text)
    table, problems = _read(tmp_path, text)
    assert table is None and len(problems) == 1, name
    assert f"not valid JSON at line {python.value.lineno}, column {python.value.colno}: " in problems[0].message


def test_valid_json_with_lookalikes_in_strings_reads_as_python_reads_it(tmp_path, windows):
    table, problems = _read(tmp_path, TEXT)
    assert problems == []
    assert json.dumps(_as_records(table)) == json.dumps(json.loads(TEXT))


def test_the_column_counts_characters_not_bytes(tmp_path):
    text = '[{"name": "Zürich – 東京", "x": nan}]'
    with pytest.raises(json.JSONDecodeError) as python:
        json.loads(text)
    _, problems = _read(tmp_path, text)
    assert f"line 1, column {python.value.colno}:" in problems[0].message


def test_a_bare_word_after_an_escaped_backslash_closing_a_string_is_found(tmp_path, windows):
    """`"a\\\\"` ends with an escaped backslash, so its last quote closes the string: a `nan` after it is outside."""
    text = json.dumps([{"p": "a\\", "q": 1}] * 30, indent=1).replace('"q": 1', '"q": nan', 1)
    with pytest.raises(json.JSONDecodeError) as python:
        json.loads(text)
    _, problems = _read(tmp_path, text)
    assert f"line {python.value.lineno}, column {python.value.colno}:" in problems[0].message


STRINGS = ["héllo\u2028\x07\x1b[31mred", "\x00nul", "😀 outside the basic plane", "tab\there", "東京", "\u007f", "",
           "\\", '"', "/", "form\x0cfeed back\x08space new\nline return\r"]  # written as \\f \\b \\n \\r


@pytest.mark.parametrize("ensure_ascii", [True, False])
def test_unicode_control_characters_and_escapes_come_back_as_python_reads_them(tmp_path, windows, ensure_ascii):
    records = [{"token": s, "extra": {"s": s}} for s in STRINGS] + [{"token": "x" * 100_000}]
    text = json.dumps(records, ensure_ascii=ensure_ascii)  # ensure_ascii: "😀" as the escaped pair \ud83d\ude00
    table, problems = _read(tmp_path, text)
    assert problems == []
    assert _as_records(table) == json.loads(text)


def test_every_escape_json_allows_reads_as_python_reads_it(tmp_path, windows):
    """The escapes json.dumps never writes (\\/, upper-case hex) and every short one, in field values and names."""
    text = r'[{"token": "a\/b\u00E9\u00e9\b\f\n\r\t\"\\", "k\u0065y": "\/"}]'
    table, problems = _read(tmp_path, text)
    assert problems == []
    assert _as_records(table) == json.loads(text) == [{"token": 'a/béé\b\f\n\r\t"\\', "key": "/"}]


@pytest.mark.parametrize("text, what", [
    (b'[{"token": "a\\ud800b"}]', "half a surrogate pair"),
    (b'[{"token": "a\\udc00"}]', "half a surrogate pair"),
    (b'[{"token": "\xff"}]', "not UTF-8"),
    (b'[{"token": "\xed\xa0\x80"}]', "not UTF-8"),  # a surrogate encoded in UTF-8: Python's decoder refuses it too
    (b'[{"token": "\xc0\xaf"}]', "not UTF-8"),  # an overlong "/"
    (b'[{"token": "ab\xe6\x9d"}]', "not UTF-8"),  # a cut sequence
])
def test_text_no_utf8_column_can_hold_is_refused(tmp_path, text, what):
    table, problems = _read(tmp_path, text)
    assert table is None and what in problems[0].message and problems[0].file == "table.json"


@pytest.mark.parametrize("text, message", [
    ("", "expected a JSON array of records, but the file is empty"),
    ("{}", "expected a JSON array of records, but the file is a JSON object"),
    ("null", "expected a JSON array of records, but the file starts with 'n'"),
    ("\ufeff[]", "expected a JSON array of records, but the file starts with '\\ufeff'"),
    ("[", "not valid JSON at line 1, column 2: the file ends before the JSON array is closed"),
    ('[{"token": "a"}', "not valid JSON at line 1, column 16: the file ends before the JSON array is closed"),
    ('[{"token": "a"}]\n}garbage', "not valid JSON at line 2, column 1: more data after the JSON array"),
])
def test_a_file_that_is_not_an_array_of_records_is_named(tmp_path, text, message):
    table, problems = _read(tmp_path, text)
    assert table is None and [p.message for p in problems] == [message]


def test_nesting_up_to_the_limit_is_kept_and_deeper_is_refused(tmp_path):
    depth = json_scan.MAX_DEPTH
    table, problems = _read(tmp_path, '[{"x": ' + "[" * depth + "]" * depth + "}]")
    assert problems == [] and json.loads(table.table.column("x")[0].as_py()) == json.loads("[" * depth + "]" * depth)
    table, problems = _read(tmp_path, '[{"x": ' + "[" * (depth + 1) + "]" * (depth + 1) + "}]")
    assert table is None and f"nested deeper than {depth} levels" in problems[0].message


def test_a_repeated_key_is_named_with_its_record(tmp_path):
    table, problems = _read(tmp_path, '[{"token": "a"}, {"token": "b", "x": 1, "x": 2}]')
    assert table is None and [(p.index, p.token, p.message) for p in problems] == [(1, "b", 'record has duplicate key "x"')]


def test_an_escaped_spelling_of_a_field_name_is_that_field(tmp_path):
    table, problems = _read(tmp_path, '[{"tok\\u0065n": "a", "\\u0078": 1}, {"token": "b", "x": 2}]')
    assert problems == [] and table.table.column("token").to_pylist() == ["a", "b"]
    assert table.json_fields == ["x"] and table.layouts == []


def test_fields_that_appear_late_and_key_orders_are_kept_across_windows(tmp_path, monkeypatch):
    monkeypatch.setattr(table_scan, "WINDOW_BYTES", 64)
    records = [{"token": f"t{i}"} for i in range(50)] + [{"late": [1, 2.5], "token": "z"}, {"token": "y", "other": None}]
    table, problems = _read(tmp_path, json.dumps(records))
    assert problems == []
    assert table.key_order == ["token", "late", "other"]
    assert _as_records(table) == records


@pytest.mark.parametrize("seed", range(40))
def test_junk_bytes_anywhere_are_refused_exactly_when_python_refuses_them(tmp_path, seed):
    """A byte inserted, deleted or changed at a random place of a small file: read iff Python's json reads it (and
    gives an array of objects without repeated keys), then with Python's values; refused otherwise, never a crash."""
    rng = random.Random(seed)
    text = json.dumps([{"token": "a", "v": [1, 2.5e3, -0.0, None, True], "o": {"k": "é\\n"}}, {"token": None, "n": 12}])
    for _ in range(25):
        at = rng.randrange(len(text) + 1)
        junk = rng.choice(list('[]{},:"\\ 0-.eE+tfnNIa\t\n') + ["\x01"])
        edited = rng.choice([text[:at] + junk + text[at:], text[:at] + text[at + 1:], text[:at] + junk + text[at + 1:]])
        try:
            expected = json.loads(edited, object_pairs_hook=_no_repeats)
            ok = isinstance(expected, list) and all(isinstance(r, dict) for r in expected)
            ok = ok and all(r.get("token") is None or isinstance(r.get("token"), str) for r in expected)
        except (json.JSONDecodeError, ValueError):
            ok = False
        table, problems = _read(tmp_path, edited)
        assert (table is not None) == ok, (edited, problems)
        if ok:
            assert json.dumps(_as_records(table)) == json.dumps(expected), edited


def _no_repeats(pairs):
    keys = [k for k, _ in pairs]
    if len(set(keys)) != len(keys):
        raise ValueError("repeated key")
    return dict(pairs)


def test_every_truncation_is_refused(tmp_path):
    text = json.dumps([{"token": "a", "v": [1, 2.5]}, {"token": "b"}], indent=1)
    for cut in range(1, len(text.rstrip())):
        table, problems = _read(tmp_path, text[:cut])
        assert table is None and "not valid JSON" in problems[0].message or problems[0].message.startswith(
            "expected a JSON array"), cut


def test_a_string_over_the_limit_is_refused_naming_record_and_field(tmp_path, monkeypatch):
    monkeypatch.setattr(table_scan, "MAX_STRING_BYTES", 1000)
    table, problems = _read(tmp_path, json.dumps([{"token": "a"}, {"token": "b", "note": "x" * 1001}]))
    assert table is None
    assert [(p.index, p.token, p.message) for p in problems] == [
        (1, "b", "field 'note' holds a string longer than 1,000 bytes (the longest a table may hold)")]
    table, problems = _read(tmp_path, json.dumps([{"token": "x" * 1000, "note": "x" * 998}]))  # raw JSON: 1,000 bytes
    assert problems == [] and table.table.column("note").to_pylist() == ['"' + "x" * 998 + '"']


def test_a_record_over_the_limit_is_refused_without_reading_it_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(table_scan, "WINDOW_BYTES", 64)
    monkeypatch.setattr(table_scan, "MAX_RECORD_BYTES", 256)
    table, problems = _read(tmp_path, json.dumps([{"token": "a"}, {"token": "b", "n": list(range(200))}]))
    assert table is None and [(p.index, p.message) for p in problems] == [
        (1, "record is longer than 0 MiB (the longest a table may hold)")]


def test_the_kinds_matrix_is_one_uint8_per_record_and_field_with_each_values_json_kind(tmp_path, monkeypatch):
    """`Scanned.kinds` holds (records, fields) uint8 codes (the documented type: one byte per value, so a table of
    millions of records and dozens of fields stays small), a field first seen in a later window included; each code
    is the JSON kind of the value written by hand below."""
    monkeypatch.setattr(table_scan, "WINDOW_BYTES", 64)
    records = [{"token": f"t{i}"} for i in range(30)] + [
        {"token": "a", "late": 7, "other": None}, {"token": "b", "late": "x", "other": [1, 2]},
        {"token": None, "late": 2.5, "other": True}, {"token": "c", "late": {"k": 1}, "other": False}]
    path = tmp_path / "table.json"
    path.write_text(json.dumps(records))
    scanned, problems = table_scan.scan_table(path, SCHEMA.fields, 1)  # from just after the opening "["
    assert problems == []
    assert scanned.kinds.dtype == "uint8" and scanned.kinds.shape == (len(records), 3)
    assert list(scanned.columns) == ["token", "late", "other"]
    j = json_scan
    expected = [(j.STRING, j.ABSENT, j.ABSENT)] * 30 + [
        (j.STRING, j.INT, j.NULL), (j.STRING, j.STRING, j.ARRAY), (j.NULL, j.FLOAT, j.TRUE),
        (j.STRING, j.OBJECT, j.FALSE)]
    assert [tuple(int(v) for v in row) for row in scanned.kinds] == expected
