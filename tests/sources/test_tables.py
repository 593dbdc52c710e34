"""The table reader's contract on single files: an empty array, leading whitespace longer than a read, bytes
that are not UTF-8, records that are not objects, and a dataroot whose path holds a quote (DuckDB reads it from
SQL text). Expectations are written out by hand."""

from __future__ import annotations

import json
import shutil

import duckdb
import pyarrow as pa

from nuparquet.problems import Problem
from nuparquet.schemas import table_schemas
from nuparquet.sources.tables import _read_one, read_tables

from conftest import SYNTH_VERSION


def read(path, table: str = "attribute"):
    with duckdb.connect() as con:
        return _read_one(con, path, table_schemas()[table])


def test_an_empty_array_after_more_whitespace_than_one_read_is_an_empty_table_of_the_schema_s_types(tmp_path):
    path = tmp_path / "attribute.json"
    path.write_text(" " * 4095 + "[\n" + " " * 5000 + "]")  # "[" ends the first 4096-byte read, "]" is in the third
    table, problems = read(path)
    schema = table_schemas()["attribute"]
    assert problems == []
    assert table.name == "attribute" and table.path == path and table.key_order == schema.names
    assert table.table.num_rows == 0
    assert table.table.schema == pa.schema([pa.field(f.name, f.arrow_type) for f in schema.fields])


def test_a_file_that_does_not_start_with_an_array_is_named_even_when_it_is_not_utf8(tmp_path):
    path = tmp_path / "attribute.json"
    path.write_bytes(b"\xff\xfe[]")
    assert read(path) == (None, [Problem("attribute.json", "expected a JSON array of records, but the file starts "
                                                           "with '\ufffd'")])
    path.write_text('{"token": "a"}')
    assert read(path) == (None, [Problem("attribute.json", "expected a JSON array of records, but the file is a "
                                                           "JSON object")])


def test_records_that_are_not_objects_are_named_by_index(tmp_path):
    path = tmp_path / "attribute.json"
    path.write_text(json.dumps([{"token": "a", "name": "n", "description": "d"}, [1, 2], "x"]))
    assert read(path) == (None, [Problem("attribute.json", "record is a JSON array, not an object", 1),
                                 Problem("attribute.json", "record is a JSON varchar, not an object", 2)])


def test_a_dataroot_whose_path_holds_a_quote_reads_like_any_other(synth_root, tmp_path):
    root = tmp_path / "it's data"
    shutil.copytree(synth_root / SYNTH_VERSION, root / SYNTH_VERSION)
    result = read_tables(root, SYNTH_VERSION)
    assert result.problems == []
    expected = len(json.loads((root / SYNTH_VERSION / "sample_data.json").read_text()))
    assert result.tables["sample_data"].table.num_rows == expected
