"""The schema language's types and dataset metadata: every spelling parses to the Arrow type it names,
malformed spellings are refused, and file-level metadata reaches the written Parquet footer and the
fingerprint."""

from __future__ import annotations

import json

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from nuparquet.conversion.write import write_parquet
from nuparquet.schemas import Field, Schema, fingerprint, parse_type


@pytest.mark.parametrize("spec, expected", [
    ("uint8", pa.uint8()), ("uint16", pa.uint16()), ("uint32", pa.uint32()), ("uint64", pa.uint64()),
    ("int32", pa.int32()), ("float32", pa.float32()), ("binary", pa.binary()), ("large_binary", pa.large_binary()),
    ("fixed_size_list<float32>[4]", pa.list_(pa.float32(), 4)),
    ("fixed_size_list<fixed_size_list<float64>[3]>[3]", pa.list_(pa.list_(pa.float64(), 3), 3)),
    ("list<uint16>", pa.list_(pa.uint16())),
    ("struct<x: float64, n: uint8>", pa.struct([("x", pa.float64()), ("n", pa.uint8())])),
    ("list<struct<start_pose: fixed_size_list<float64>[3], shape: string>>",
     pa.list_(pa.struct([("start_pose", pa.list_(pa.float64(), 3)), ("shape", pa.string())]))),
    ("struct<incoming: list<string>, outgoing: list<string>>",
     pa.struct([("incoming", pa.list_(pa.string())), ("outgoing", pa.list_(pa.string()))])),
    ("timestamp[us, UTC]", pa.timestamp("us", tz="UTC")),
    ("dictionary<string>", pa.dictionary(pa.int32(), pa.string())),
])
def test_every_type_spelling_parses_to_its_arrow_type(spec, expected):
    assert parse_type(spec) == expected


@pytest.mark.parametrize("spec", ["uint7", "list<int64", "struct<a int64>", "struct<a: int64", "fixed_size_list<int8>",
                                  "fixed_size_list<int8>[x]", "int64 extra", "struct<>", "",
                                  "struct(a: int64>", "list(int64>"])
def test_malformed_spellings_are_refused(spec):
    with pytest.raises(ValueError, match="unknown type"):
        parse_type(spec)


def _schema(metadata: dict) -> Schema:
    return Schema(name="layer", kind="dataset", version=1, doc="", metadata=metadata,
                  fields=(Field("token", "string"), Field("geometry", "binary"), Field("label", "uint8")))


def test_dataset_metadata_reaches_the_parquet_footer(tmp_path):
    geo = {"version": "1.1.0", "primary_column": "geometry", "columns": {"geometry": {"encoding": "WKB"}}}
    schema = _schema({"geo": geo, "note": "plain text"}).arrow_schema()
    table = pa.table({"token": ["a"], "geometry": [b"\x01"], "label": [3]}).cast(schema)
    write_parquet(table, tmp_path / "layer")
    footer = pq.read_metadata(tmp_path / "layer" / "part-00000.parquet").metadata
    assert json.loads(footer[b"geo"]) == geo
    assert footer[b"note"] == b"plain text"
    assert pq.read_schema(tmp_path / "layer" / "part-00000.parquet").field("label").type == pa.uint8()


def test_fingerprint_covers_types_and_metadata():
    base = _schema({}).arrow_schema()
    assert fingerprint(base) == fingerprint(_schema({}).arrow_schema())
    assert fingerprint(base) != fingerprint(_schema({"geo": {"version": "1.1.0"}}).arrow_schema())
    assert fingerprint(_schema({"geo": {"version": "1.1.0"}}).arrow_schema()) != \
        fingerprint(_schema({"geo": {"version": "1.0.0"}}).arrow_schema())
    widened = pa.schema([f if f.name != "label" else pa.field("label", pa.uint16(), nullable=False) for f in base])
    assert fingerprint(base) != fingerprint(widened)


def test_an_unknown_type_name_is_refused_naming_it_and_the_spelling():
    from nuparquet.schemas import parse_type

    with pytest.raises(ValueError) as error:
        parse_type("list<float65>")
    assert str(error.value) == "unknown type in schema file: 'list<float65>' (no type 'float65')"


def test_a_struct_without_its_opening_bracket_is_refused_saying_what_was_expected():
    with pytest.raises(ValueError) as error:
        parse_type("struct[a: int64>")
    assert str(error.value) == "unknown type in schema file: 'struct[a: int64>' (expected < at token 1)"


def test_a_schema_file_s_sort_order_and_metadata_are_read(tmp_path):
    """`_load` of a schema file (read at test time: the loaders' cache was filled before) keeps the rows' sort
    order, the file-level metadata and the further-columns text as the JSON gives them, and their defaults when
    absent; the shipped frames schema's sort order is its file's."""
    from nuparquet import schemas

    spec = {"name": "layer", "kind": "dataset", "version": 2, "doc": "One row per record.",
            "sort_by": ["location", "token"], "metadata": {"geo": {"version": "1.1.0"}, "note": "plain text"},
            "extra": "the record's own fields", "fields": [{"name": "token", "type": "string", "doc": "Its token."}]}
    (tmp_path / "layer.json").write_text(json.dumps(spec))
    loaded = schemas._load(tmp_path / "layer.json")
    assert loaded.sort_by == ("location", "token") and loaded.metadata == spec["metadata"]
    assert loaded.extra == "the record's own fields" and loaded.names == ["token"]
    assert json.loads(loaded.arrow_schema().metadata[b"geo"]) == {"version": "1.1.0"}
    bare = {k: v for k, v in spec.items() if k not in ("sort_by", "metadata", "extra")}
    (tmp_path / "bare.json").write_text(json.dumps(bare))
    plain = schemas._load(tmp_path / "bare.json")
    assert (plain.sort_by, plain.metadata, plain.extra) == ((), {}, "")
    frames = schemas._schema_dir() / "frames.json"
    assert schemas._load(frames).sort_by == tuple(json.loads(frames.read_text())["sort_by"])


def test_the_schema_docs_list_a_dataset_s_sort_order_and_file_metadata(monkeypatch):
    """docs_markdown of one dataset with a sort order, file metadata and further columns (no shipped schema has
    metadata yet): each gets its line after the doc, and the page keeps its title and what came before."""
    from nuparquet import schemas

    layer = Schema(name="layer", kind="dataset", version=1, doc="One row per record.", sort_by=("location", "token"),
                   metadata={"geo": {"version": "1.1.0"}, "note": "plain text"}, extra="the record's own fields",
                   fields=(Field("token", "string", doc="Its token."),))
    monkeypatch.setattr(schemas, "dataset_schemas", lambda: {"layer": layer})
    monkeypatch.setattr(schemas, "table_schemas", lambda: {})
    lines = schemas.docs_markdown().split("\n")
    assert lines[0] == "# nuparquet datasets" and lines[4:6] == ["## Derived datasets", ""]
    assert lines[6:16] == ["### `layer`", "", "One row per record.", "",
                           "Rows sorted by: `location`, `token`.", "",
                           "File metadata: `geo`, `note`.", "",
                           "Further columns: the record's own fields", ""]
    assert lines[16:19] == ["| column | type | description |", "|---|---|---|", "| `token` | `string` | Its token. |"]
