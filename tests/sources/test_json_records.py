"""JSON records typed into Arrow and back: every record comes back equal, with its JSON types and key order; values
that cannot convert exactly are refused as problems naming the file and the record."""

from __future__ import annotations

import json
import math

import pyarrow as pa
import pytest

from nuparquet.sources.json_records import Located, to_columns, to_records


def round_trip(records, files=("f.json",), starts=(0,)):
    columns, problems = to_columns(records, Located(list(files), list(starts)), "message")
    assert problems == []
    back = to_records(columns.table.to_pylist(), columns.keys, columns.json_fields, columns.int_values,
                      columns.key_orders)
    return columns, back


def same(a, b):
    return json.dumps(a) == json.dumps(b)  # same values, JSON types (1 vs 1.0) and key order


def test_types_and_exact_round_trip():
    records = [
        {"utime": 1, "value": 0.5, "vec": [1.0, 2.5, 0.0], "flag": True, "name": "a", "stats": {"max": 1, "m": 0.5},
         "ids": ["x", "y"], "var": [1.0], "none": None},
        {"utime": 2, "value": 0, "vec": [1, 2.5, float("nan")], "flag": False, "name": "b", "stats": None,
         "ids": ["z"], "var": [2.0, 3.0], "none": None},
    ]
    columns, back = round_trip(records)
    schema = columns.table.schema
    assert schema.field("utime").type == pa.int64() and schema.field("value").type == pa.float64()
    assert schema.field("vec").type == pa.list_(pa.float64(), 3)  # fixed size: same length everywhere
    assert schema.field("var").type == pa.list_(pa.float64())  # variable length
    assert schema.field("ids").type == pa.list_(pa.string())
    assert columns.json_fields == ["stats"]
    assert columns.int_values == {"value": [1], "vec": [[1, 0]]}
    assert same(back[0], records[0])
    assert back[1]["value"] == 0 and type(back[1]["value"]) is int and type(back[1]["vec"][0]) is int
    assert math.isnan(back[1]["vec"][2]) and back[1]["stats"] is None


def test_each_record_keeps_its_key_order():
    records = [{"a": 1, "b": 2.0}, {"b": 3.0, "a": 4}, {"a": 5, "b": 6.0}]
    columns, back = round_trip(records)
    assert columns.key_orders == {1: ["b", "a"]}
    assert [list(r) for r in back] == [["a", "b"], ["b", "a"], ["a", "b"]]


def test_null_list_elements_stay_null():
    records = [{"v": [1.0, None]}, {"v": [0.5, 2.0]}]
    columns, back = round_trip(records)
    assert back == records
    # every list as long (2): a fixed-size list as without the null (test_types_and_exact_round_trip), the null kept
    assert columns.table.schema.field("v").type == pa.list_(pa.float64(), 2)
    assert columns.table.column("v").to_pylist() == [[1.0, None], [0.5, 2.0]]


@pytest.mark.parametrize("records, message, index", [
    ([{"a": 1.0}, {"a": "x"}, {"a": 2.0}], "field 'a' is a str where the others hold float values", 1),
    ([{"a": 1, "b": 2}, {"a": 1}], "message lacks b", 1),
    ([{"a": 1}, {"a": 1, "c": 2}], "message has extra c", 1),
    ([{"a": 1}, {"a": 2**63}], "outside int64", 1),
])
def test_values_that_cannot_convert_are_problems(records, message, index):
    columns, problems = to_columns(records, Located(["can_bus/x.json"], [0]), "message")
    assert columns is None and problems
    assert problems[0].file == "can_bus/x.json" and message in problems[0].message and problems[0].index == index


def test_every_field_with_an_integer_outside_int64_is_named_not_only_the_first():
    records = [{"a": 1, "b": 2.5, "c": 3}, {"a": 2**63, "b": "x", "c": -2**63 - 1}, {"a": 2, "b": 1.0, "c": 4}]
    columns, problems = to_columns(records, Located(["f.json"], [0]), "message")
    assert columns is None
    assert [(p.index, p.message) for p in problems] == [
        (1, f"message field 'a': integer {2**63} is outside int64"),
        (1, "message field 'b' is a str where the others hold float values"),
        (1, f"message field 'c': integer {-2**63 - 1} is outside int64")]


def test_integers_and_floats_count_as_one_kind_against_the_others():
    """2 integers and 1 float outnumber 2 strings (numbers are one kind): the strings are the odd ones, named as such;
    counted apart (2 strings against 2 integers), the numbers would be reported instead."""
    records = [{"a": 1}, {"a": "x"}, {"a": 2}, {"a": "y"}, {"a": 0.5}]
    _, problems = to_columns(records, Located(["can_bus/x.json"], [0]), "message")
    assert [(p.index, p.message) for p in problems] == [
        (1, "message field 'a' is a str where the others hold float values"),
        (3, "message field 'a' is a str where the others hold float values")]


def test_integers_beyond_float64_precision_among_floats_are_refused():
    _, problems = to_columns([{"a": 0.5}, {"a": 2**53 + 1}], Located(["f.json"], [0]), "message")
    assert problems and "beyond 2**53" in problems[0].message
    assert [(p.file, p.message) for p in problems] == [
        ("f.json", "message field 'a': integer 9007199254740993 among floats is beyond 2**53 and would not convert "
                   "exactly")]


def test_no_records_give_an_empty_table_and_come_back_as_no_records(tmp_path):
    """An empty JSON array (an extra table a version ships empty, as T4's object_ann can be): no columns, no rows,
    no problem, and nothing written back."""
    from nuparquet.sources.tables import read_extra_table

    columns, back = round_trip([])
    assert columns.table.num_rows == 0 and columns.table.num_columns == 0 and columns.keys == [] and back == []
    path = tmp_path / "object_ann.json"
    path.write_text("[]")
    table, problems = read_extra_table(path)
    assert problems == [] and table.name == "object_ann" and table.table.num_rows == 0


def test_problems_name_the_file_and_the_record_within_it():
    records = [{"a": 1.0}] * 3 + [{"a": 1.0}, {"a": "x"}]
    _, problems = to_columns(records, Located(["first.json", "second.json"], [0, 3]), "message")
    assert (problems[0].file, problems[0].index) == ("second.json", 1)


def test_an_extra_table_that_is_not_json_is_named_with_the_parser_s_reason(tmp_path):
    from nuparquet.sources.tables import read_extra_table

    path = tmp_path / "object_ann.json"
    path.write_text('[{"token": "a",}]')
    table, problems = read_extra_table(path)
    assert table is None and len(problems) == 1
    assert problems[0].file == "object_ann.json"
    assert problems[0].message.startswith("not valid JSON (Expecting property name enclosed in double quotes")


def test_an_extra_table_names_a_record_by_its_0_based_index_and_keeps_each_record_s_key_order(tmp_path):
    from nuparquet.sources.tables import read_extra_table

    path = tmp_path / "vehicle_state.json"
    path.write_text(json.dumps([{"token": "a", "speed": 1.0}, {"token": "b"}]))
    table, problems = read_extra_table(path)
    assert table is None
    assert [(p.file, p.index, p.message) for p in problems] == [
        ("vehicle_state.json", 1, "record lacks speed (the first record has token, speed)")]
    path.write_text(json.dumps([{"token": "a", "speed": 1.0}, {"speed": 2.0, "token": "b"}]))
    table, problems = read_extra_table(path)
    assert problems == [] and table.name == "vehicle_state"
    assert table.inferred["key_orders"] == {"1": ["speed", "token"]} and table.inferred["keys"] == ["token", "speed"]


def test_range_facts_renumber_a_later_files_records_from_its_first():
    """Records of several files typed together (one CAN bus message type over scenes): the facts of file 2
    (records 3..5) name its records 0..2, an integer inside a list by (record, element)."""
    import pyarrow as pa

    from nuparquet.sources.json_records import Columns, range_facts

    columns = Columns(pa.table({"v": [0.0] * 6}), ["v"], int_values={"v": [1, 4], "pos": [[0, 2], [5, 1]]},
                      key_orders={2: ["b", "a"], 3: ["v", "utime"]})
    assert range_facts(columns, 0, 3) == {"int_values": {"v": [1], "pos": [[0, 2]]}, "key_orders": {"2": ["b", "a"]}}
    assert range_facts(columns, 3, 6) == {"int_values": {"v": [1], "pos": [[2, 1]]}, "key_orders": {"0": ["v", "utime"]}}
    assert range_facts(columns, 6, 6) == {}
