"""Issue 27 part 3: no value changes silently inside a list. Every JSON type in every list field of every table is
either kept exactly (a number float64 holds, an integer literal that float64 holds exactly, which comes back as an
integer) or refused naming the file, the record (index and token) and the field. Expectations come from Python's
json and Python's float, not from the reader."""

from __future__ import annotations

import json
import math

import pytest

from nuparquet.schemas import table_schemas
from nuparquet.sources.tables import read_table

from conftest import SYNTH_VERSION

# Every list field of the tables: (table, field).
LIST_FIELDS = [(name, f.name) for name, schema in table_schemas().items() for f in schema.fields
               if f.type.startswith(("fixed_size_list", "list"))]
NOT_A_NUMBER = ["677.3601837010744", None, True, False, {"x": 1}, [1.0], "", "NaN"]
NOT_A_STRING = [0, -1e308, math.nan, math.inf, None, True, {"x": "a"}, ["a"], 2**70]


def _records(synth_root, table: str) -> list[dict]:
    return json.loads((synth_root / SYNTH_VERSION / f"{table}.json").read_text())


def _read(tmp_path, table: str, records: list[dict]):
    path = tmp_path / f"{table}.json"
    path.write_text(json.dumps(records, indent=2))
    return read_table(path, table_schemas()[table])


def _first_with(records: list[dict], field: str) -> int:
    return next(i for i, r in enumerate(records) if isinstance(r.get(field), list) and r[field]
                and (not isinstance(r[field][0], list) or r[field][0]))


def test_every_list_field_is_covered():
    assert {f for _, f in LIST_FIELDS} >= {"translation", "rotation", "size", "camera_intrinsic", "attribute_tokens",
                                           "log_tokens"}


@pytest.mark.parametrize("table, field", LIST_FIELDS)
def test_anything_but_the_elements_type_inside_a_list_is_refused_naming_record_and_field(synth_root, tmp_path,
                                                                                         table, field):
    records = _records(synth_root, table)
    if not any(isinstance(r.get(field), list) and r[field] for r in records):
        records[0][field] = ["a"] if table_schemas()[table].field(field).type == "list<string>" else [1.0, 2.0, 3.0]
    index = _first_with(records, field)
    strings = table_schemas()[table].field(field).type == "list<string>"
    for bad in NOT_A_STRING if strings else NOT_A_NUMBER:
        edited = json.loads(json.dumps(records))
        value = edited[index][field]
        if isinstance(value[0], list):
            value[1][2] = bad
        else:
            value[-1] = bad
        table_, problems = _read(tmp_path, table, edited)
        assert table_ is None, (field, bad)
        word = "a list of strings" if strings else ("a 3x3 list of numbers or []" if isinstance(value[0], list)
                                                    else "a list of numbers")
        assert [(p.file, p.index, p.token) for p in problems] == [(f"{table}.json", index, edited[index]["token"])]
        assert problems[0].message.startswith(f"field {field!r} must be {word}, got ["), (bad, problems[0].message)


FLOAT_FIELDS = [(t, f) for t, f in LIST_FIELDS if "float" in table_schemas()[t].field(f).type]


@pytest.mark.parametrize("table, field", FLOAT_FIELDS)
@pytest.mark.parametrize("value", [2**53, -(2**53), 2**64, -(2**64), 2**70, 2**1000, 0, -0, 1])
def test_integers_float64_holds_exactly_are_kept_and_come_back_as_integers(synth_root, tmp_path, table, field, value):
    records = _records(synth_root, table)
    index = _first_with(records, field)
    row = records[index][field]
    if isinstance(row[0], list):
        row[0][0] = value
    else:
        row[0] = value
    assert float(value) == value  # the premise: float64 holds it
    source, problems = _read(tmp_path, table, records)
    assert problems == []
    marks = source.table.column("_json_types").to_pylist()[index]
    got = source.table.column(field).to_pylist()[index]
    first = got[0][0] if isinstance(got[0], list) else got[0]
    assert first == float(value) and any(m.startswith(f"{field}:i") for m in marks)


@pytest.mark.parametrize("table, field", FLOAT_FIELDS)
@pytest.mark.parametrize("value", [2**53 + 1, -(2**53) - 1, 2**64 - 1, -(2**64) + 1, 2**63 - 1, -(2**63) + 1,
                                   18446744073709551615, 10**300, 10**400])
def test_integers_float64_would_change_are_refused_naming_record_and_field(synth_root, tmp_path, table, field, value):
    records = _records(synth_root, table)
    index = _first_with(records, field)
    row = records[index][field]
    if isinstance(row[0], list):
        row[0][0] = value
    else:
        row[0] = value
    assert float(value) != value if abs(value) < 10**308 else True
    source, problems = _read(tmp_path, table, records)
    assert source is None
    assert [(p.file, p.index, p.token) for p in problems] == [(f"{table}.json", index, records[index]["token"])]
    assert problems[0].message.startswith(f"field {field!r} holds an integer that float64 cannot hold exactly: [")


@pytest.mark.parametrize("value, kept", [(-(2**63), True), (2**63 - 1, True), (-(2**63) - 1, False), (2**63, False),
                                         (2**64 - 1, False), (2**64, False), (2**70, False), (-(2**70), False)])
@pytest.mark.parametrize("field", ["num_lidar_pts", "num_radar_pts"])
def test_integer_fields_keep_all_of_int64_and_refuse_beyond(synth_root, tmp_path, value, kept, field):
    records = _records(synth_root, "sample_annotation")
    records[2][field] = value
    source, problems = _read(tmp_path, "sample_annotation", records)
    if kept:
        assert problems == [] and source.table.column(field).to_pylist()[2] == value
    else:
        assert source is None and [(p.index, p.message) for p in problems] == [
            (2, f"field {field!r} must be an integer within the 64-bit range, got {value}")]


def test_a_float_written_integer_beside_fractions_is_refused_when_float64_would_change_it(synth_root, tmp_path):
    """width takes floats (Lyft writes NaN); with a fraction the column is float64, so its integers must be exact."""
    records = _records(synth_root, "sample_data")
    records[0]["width"] = 0.5
    records[1]["width"] = 2**60 + 1
    source, problems = _read(tmp_path, "sample_data", records)
    assert source is None and [(p.index, p.message) for p in problems] == [
        (1, f"field 'width' holds the integer {2**60 + 1} among floats: float64 cannot hold it exactly")]
    records[1]["width"] = 2**60
    source, problems = _read(tmp_path, "sample_data", records)
    assert problems == [] and source.float_fields == ["width"]
    assert source.table.column("width").to_pylist()[:2] == [0.5, float(2**60)]
