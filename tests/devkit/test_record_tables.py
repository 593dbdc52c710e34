"""nuparquet.devkit.tables on hand-made Arrow data: the getters give json.load's values for every column type, chunk
layout, slice and null; tables read from many row groups keep their order; token lookups; the Table sequence."""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from nuparquet.devkit import ReadOnly
from nuparquet.devkit.columns import Columns, TokenIndex, getter, read_table, shared_strings, token_bytes
from nuparquet.devkit.tables import Table

VALUES = {
    "text": ["a", "", "héllo", None, "zz" * 40, "a", "b"],
    "token": [f"{i:032x}" for i in range(7)],
    "number": [1, None, -5, 2**62, 0, 7, 8],
    "real": [0.5, float("nan"), None, -0.0, 1e300, 2.0, 3.0],
    "flag": [True, False, None, True, True, False, True],
    "triple": [[1.0, 2.0, 3.0], None, [0.1, 0.2, 0.3], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0], [0.0, 0.0, 0.0],
               [1.5, 2.5, 3.5]],
    "matrix": [[[1.0, 0.0], [0.0, 1.0]], None, [[2.0, 3.0], [4.0, 5.0]], None, [[6.0, 7.0], [8.0, 9.0]],
               [[0.5, 0.5], [0.5, 0.5]], [[1.0, 2.0], [3.0, 4.0]]],
    "names": [["x", "y"], [], None, ["z"], ["x", "x", "y"], [], ["y"]],
}
TYPES = {"text": pa.string(), "token": pa.string(), "number": pa.int64(), "real": pa.float64(), "flag": pa.bool_(),
         "triple": pa.list_(pa.float64(), 3), "matrix": pa.list_(pa.list_(pa.float64(), 2), 2),
         "names": pa.list_(pa.string())}


def same(a, b) -> bool:
    return json.dumps(a) == json.dumps(b) and [type(x) for x in a] == [type(x) for x in b]


@pytest.mark.parametrize("layout", ["whole", "chunks of 3", "uneven chunks", "slice"])
def test_getters_return_json_loads_values_for_every_type_and_chunk_layout(layout):
    for name, values in VALUES.items():
        array = pa.array(values, TYPES[name])
        if layout == "chunks of 3":
            array = pa.chunked_array([array.slice(0, 3), array.slice(3, 3), array.slice(6)])
        elif layout == "uneven chunks":
            array = pa.chunked_array([array.slice(0, 1), array.slice(1, 0), array.slice(1, 4), array.slice(5)])
        elif layout == "slice":  # an array that starts inside its buffers
            array = pa.array([values[-1]] * 2 + values, TYPES[name]).slice(2)
        got = [getter(array)(i) for i in range(len(values))]
        assert same(got, values), (name, layout, got)


def test_empty_list_fields_read_null_as_an_empty_list_and_json_text_is_parsed():
    intrinsic = pa.array([None, [[1.0, 0.0], [0.0, 1.0]]], TYPES["matrix"])
    assert [getter(intrinsic, empty_list=True)(i) for i in range(2)] == [[], [[1.0, 0.0], [0.0, 1.0]]]
    text = pa.array(['{"a": [1, 2.5, null]}', None, "NaN"])
    got = [getter(text, json_text=True)(i) for i in range(3)]
    assert got[:2] == [{"a": [1, 2.5, None]}, None] and np.isnan(got[2]) and type(got[0]["a"][0]) is int


def test_repeated_strings_become_shared_dictionary_values_and_unique_ones_stay_plain():
    repeated = pa.chunked_array([pa.array(["s1", "s2"] * 40)])
    encoded = shared_strings(repeated)
    assert pa.types.is_dictionary(encoded.type)
    read = getter(encoded)
    assert [read(i) for i in range(80)] == ["s1", "s2"] * 40 and read(0) is read(2)
    unique = pa.chunked_array([pa.array([f"u{i}" for i in range(80)])])
    assert shared_strings(unique) is unique


def test_tables_of_many_row_groups_and_files_are_read_in_order(tmp_path):
    files = []
    for part in range(3):
        table = pa.table({"token": [f"{part}-{i:04d}" for i in range(50)], "n": list(range(50))})
        path = tmp_path / f"part-{part:05d}.parquet"
        pq.write_table(table, path, row_group_size=7)
        files.append(str(path))
    table = read_table(files)
    assert table.column("token").to_pylist() == [f"{p}-{i:04d}" for p in range(3) for i in range(50)]
    assert table.column("n").num_chunks > 3  # left in its row groups
    read = getter(table.column("token"))
    assert [read(i) for i in (0, 6, 7, 49, 50, 149)] == ["0-0000", "0-0006", "0-0007", "0-0049", "1-0000", "2-0049"]
    assert read_table(files, ["n", "missing"]).column_names == ["n"]


def test_token_index_finds_rows_and_refuses_what_is_not_there():
    tokens = ["c" * 32, "a" * 32, "b" * 32]
    index = TokenIndex(token_bytes(pa.array(tokens)))
    assert [index.find(t) for t in tokens] == [0, 1, 2]
    for missing in ("d" * 32, "a" * 31, "a" * 33, "", None, 5):
        with pytest.raises(KeyError) as raised:
            index.find(missing)
        assert raised.value.args == (missing,)  # the devkit's dict lookup names the token
    assert index.find_all(np.array([b"b" * 32, b"x" * 32, b"c" * 32])).tolist() == [2, -1, 0]
    empty = TokenIndex(token_bytes(pa.array([], pa.string())))  # a table with no rows: every token is absent
    with pytest.raises(KeyError):
        empty.find("a" * 32)
    assert empty.find_all(np.array([b"a" * 32, b"b" * 32])).tolist() == [-1, -1]
    varied = token_bytes(pa.chunked_array([pa.array(["ab", "c"]), pa.array(["defg"])]))
    assert varied.tolist() == [b"ab", b"c", b"defg"]


def make_table(n: int = 5, **kwargs) -> Table:
    arrow = pa.table({"token": [f"t{i}" for i in range(n)], "value": list(range(n))})
    return Table("thing", n, lambda: Columns(arrow, ["token", "value"]), **kwargs)


def test_table_builds_each_record_once_by_index_token_slice_or_iteration():
    decorated = []
    table = make_table(decorate=lambda record, i: decorated.append(i) or record.setdefault("extra", i * 10))
    assert not table.loaded and len(table) == 5
    first = table[0]
    assert first == {"token": "t0", "value": 0, "extra": 0} and table.loaded
    assert table.record_of("t0") is first and table[-5] is first and table[0:1][0] is first
    assert [r["value"] for r in table] == [0, 1, 2, 3, 4] and table.index_of("t3") == 3
    assert decorated == [0, 1, 2, 3, 4]  # each record decorated once, whichever way it was reached
    assert table[::-2] == [table[4], table[2], table[0]]
    with pytest.raises(KeyError):
        table.record_of("t9")
    with pytest.raises(IndexError):
        table[5]
    with pytest.raises(TypeError, match="integers or slices"):
        table[1.0]


def test_table_refuses_every_write():
    table = make_table()
    for write in (lambda: table.append({}), lambda: table.extend([]), lambda: table.insert(0, {}),
                  lambda: table.pop(), lambda: table.remove({}), lambda: table.clear(), lambda: table.sort(),
                  lambda: table.reverse(), lambda: table.__setitem__(0, {}), lambda: table.__delitem__(0),
                  lambda: table.__iadd__([])):
        with pytest.raises(ReadOnly, match="nusc.thing is read-only"):
            write()
    assert len(table) == 5 and table + [] == list(table)


def test_a_table_whose_files_disagree_with_the_manifest_is_an_error():
    table = make_table(n=5)
    table._length = 6
    with pytest.raises(ValueError, match="6"):
        table[0]


def test_a_record_naming_a_sample_that_is_not_there_is_refused_naming_both_tokens():
    """The reverse index (`sample["anns"]`, `sample["data"]`) of an output converted with --allow-dangling: the first
    record whose sample_token is no sample's is named with that token, not a KeyError of a column."""
    from nuparquet.devkit.reverse import SampleLinks
    from nuparquet.errors import InputError

    samples = [f"{i:032x}" for i in range(3)]
    index = TokenIndex(token_bytes(pa.array(samples)))
    fine = pa.table({"token": ["a" * 32, "b" * 32], "sample_token": [samples[2], samples[0]]})
    assert SampleLinks._samples_of(index, fine, "sample_annotation").tolist() == [2, 0]
    dangling = pa.table({"token": ["a" * 32, "b" * 32, "c" * 32], "sample_token": [samples[1], "f" * 32, "e" * 32]})
    with pytest.raises(InputError, match=f"^sample_annotation {'b' * 32} names sample {'f' * 32}, which is not in "
                                         "the sample table$"):
        SampleLinks._samples_of(index, dangling, "sample_annotation")
