"""DuckDB's errors reach the user as one line without DuckDB's class prefix (the rest of a problem line already
names the file)."""

from __future__ import annotations

import duckdb
import pytest

from nuparquet.sources.tables import _duckdb_message


@pytest.mark.parametrize("raw, shown", [
    ("Invalid Input Error: Malformed JSON at byte 12 of input\nLINE 1: SELECT ...", "Malformed JSON at byte 12 of input"),
    ("Binder Error: Referenced column \"x\" not found\nCandidate bindings: ...", "Referenced column \"x\" not found"),
    ("Conversion Error: Could not convert string 'a' to INT64", "Conversion Error: Could not convert string 'a' to INT64"),
])
def test_duckdb_errors_are_shown_as_their_first_line_without_the_prefix(raw, shown):
    assert _duckdb_message(duckdb.Error(raw)) == shown
