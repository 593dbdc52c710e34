"""DuckDB's errors reach the user as one line without DuckDB's class prefix (the rest of a problem line already
names the file)."""

from __future__ import annotations

import duckdb
import pytest

from nuparquet.problems import Problem
from nuparquet.sources.tables import _duckdb_message, _duckdb_problem


@pytest.mark.parametrize("raw, shown", [
    ("Invalid Input Error: Malformed JSON at byte 12 of input\nLINE 1: SELECT ...", "Malformed JSON at byte 12 of input"),
    ("Binder Error: Referenced column \"x\" not found\nCandidate bindings: ...", "Referenced column \"x\" not found"),
    ("Conversion Error: Could not convert string 'a' to INT64", "Conversion Error: Could not convert string 'a' to INT64"),
])
def test_duckdb_errors_are_shown_as_their_first_line_without_the_prefix(raw, shown):
    assert _duckdb_message(duckdb.Error(raw)) == shown


def test_a_record_duckdb_names_gets_its_0_based_index_and_no_token_when_the_lookup_fails():
    """DuckDB counts records from 1; when the token cannot be looked up (here: the source is gone) the problem
    still names the record, without a token."""
    exc = duckdb.InvalidInputException('Invalid Input Error: JSON transform error in file "x.json", in record/value 3: '
                                       "Failed to cast value to numerical: 9223372036854775808")
    objects = "read_json_objects('/nonexistent/x.json', format='array')"
    got = _duckdb_problem(duckdb.connect(), objects, "x.json", exc)
    assert got == Problem("x.json", "record Failed to cast value to numerical: 9223372036854775808", 2, None)
