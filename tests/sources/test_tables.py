"""The table reader's contract on single files: an empty array, leading whitespace longer than a read, bytes
that are not UTF-8, records that are not objects, and a dataroot whose path holds a quote (the reader before
this one read it from SQL text). Expectations are written out by hand."""

from __future__ import annotations

import json
import shutil

import pyarrow as pa

from nuparquet.problems import Problem
from nuparquet.schemas import table_schemas
from nuparquet.sources.tables import read_table, read_tables

from conftest import SYNTH_VERSION


def read(path, table: str = "attribute"):
    return read_table(path, table_schemas()[table])


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
                                 Problem("attribute.json", "record is a JSON string, not an object", 2)])


def test_a_dataroot_whose_path_holds_a_quote_reads_like_any_other(synth_root, tmp_path):
    root = tmp_path / "it's data"
    shutil.copytree(synth_root / SYNTH_VERSION, root / SYNTH_VERSION)
    result = read_tables(root, SYNTH_VERSION)
    assert result.problems == []
    expected = len(json.loads((root / SYNTH_VERSION / "sample_data.json").read_text()))
    assert result.tables["sample_data"].table.num_rows == expected


def test_a_missing_table_is_named_and_every_other_table_is_still_read(synth_root, tmp_path):
    folder = tmp_path / SYNTH_VERSION
    shutil.copytree(synth_root / SYNTH_VERSION, folder)
    (folder / "attribute.json").unlink()  # the first table of the schema order
    (folder / "object_ann.json").write_text(json.dumps([{"token": "oa0", "bbox": [1, 2, 3, 4]}]))
    seen = []
    result = read_tables(tmp_path, SYNTH_VERSION, on_table=seen.append)
    assert result.problems == [Problem("attribute.json",
                                       f"table attribute is missing (expected {folder / 'attribute.json'})")]
    present = {name for name, s in table_schemas().items() if (folder / s.source).is_file()}
    assert set(result.tables) == present | {"object_ann"}
    assert seen[-1] == "object_ann" and seen[:len(table_schemas())] == list(table_schemas())
    stat = (folder / "scene.json").stat()
    assert result.files["scene.json"] == {"bytes": stat.st_size, "mtime": stat.st_mtime}
    assert result.files["object_ann.json"]["bytes"] == (folder / "object_ann.json").stat().st_size
    assert "attribute.json" not in result.files


def test_a_required_field_missing_from_every_record_is_named(tmp_path):
    path = tmp_path / "attribute.json"
    path.write_text(json.dumps([{"token": "a", "description": "d"}, {"token": "b", "description": "e"}]))
    assert read(path) == (None, [Problem("attribute.json", "required field 'name' is missing from every record")])


def test_every_integer_field_that_cannot_be_kept_is_named_not_only_the_last(synth_root, tmp_path):
    records = json.loads((synth_root / SYNTH_VERSION / "sample_data.json").read_text())
    records[3]["width"] = 2**70
    records[4]["timestamp"] = 2**70
    path = tmp_path / "sample_data.json"
    path.write_text(json.dumps(records))
    table, problems = read(path, "sample_data")
    assert table is None
    assert [(p.index, p.message.split(" must")[0]) for p in problems] == [(4, "field 'timestamp'"), (3, "field 'width'")]


def test_an_integer_field_of_fractions_only_is_a_float_column_without_hidden_marks(synth_root, tmp_path):
    """No record holds an integer there, so no record needs its JSON type remembered: the table holds exactly
    the schema's columns."""
    records = json.loads((synth_root / SYNTH_VERSION / "sample_data.json").read_text())
    for r in records:
        r["width"] = 0.5
    path = tmp_path / "sample_data.json"
    path.write_text(json.dumps(records))
    table, problems = read(path, "sample_data")
    assert problems == [] and table.float_fields == ["width"]
    assert table.table.column_names == list(records[0]) and table.layouts == []  # one layout: none listed
    assert table.table.column("width").type == pa.float64()


def test_null_in_an_optional_field_is_a_null_value(synth_root, tmp_path):
    records = json.loads((synth_root / SYNTH_VERSION / "sample_data.json").read_text())
    records[2]["height"] = None
    path = tmp_path / "sample_data.json"
    path.write_text(json.dumps(records))
    table, problems = read(path, "sample_data")
    assert problems == []
    heights = table.table.column("height").to_pylist()
    assert heights[2] is None and heights[:2] == [r["height"] for r in records[:2]]


def test_a_list_element_over_the_field_limit_names_its_record_and_the_first_such_element(tmp_path):
    """`attribute_tokens` holds at most 4096 bytes per token: a record with an element over it is refused, named
    by its own index and token (not the element's), with the first too-long element's length; a record whose
    element is exactly at the limit, or whose list is empty, is read."""
    limit = table_schemas()["sample_annotation"].field("attribute_tokens").max_bytes
    assert limit == 4096

    def record(token, attributes):
        return {"token": token, "sample_token": "s", "instance_token": "i", "visibility_token": "",
                "attribute_tokens": attributes, "translation": [0, 0, 0], "size": [1, 1, 1], "rotation": [1, 0, 0, 0],
                "prev": "", "next": "", "num_lidar_pts": 0, "num_radar_pts": 0}

    attributes = [["x" * limit], ["ok", "y" * (limit + 1), "z" * (limit + 900)], [], ["w" * (limit + 4)]]
    path = tmp_path / "sample_annotation.json"
    path.write_text(json.dumps([record(f"a{i}", a) for i, a in enumerate(attributes)]))
    table, problems = read(path, "sample_annotation")
    assert table is None
    assert [(p.file, p.index, p.token) for p in problems] == [("sample_annotation.json", 1, "a1"),
                                                              ("sample_annotation.json", 3, "a3")]
    for problem, length in zip(problems, (limit + 1, limit + 4)):
        assert problem.message.startswith(f"field 'attribute_tokens' holds a string of {length:,} bytes, over its "
                                          f"limit of {limit:,}: ")
    assert problems[0].message.split(": ", 1)[1].startswith('["ok", "yyy')  # the record's list, as written
