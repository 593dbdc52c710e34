"""The Arrow schemas of every dataset nuparquet reads or writes, loaded from the data files in `schemas/`.

`schemas/tables/<name>.json` describes one nuScenes source table (its fields, JSON conventions, foreign keys);
`schemas/<dataset>.json` describes a derived dataset. Nothing else in the package defines a column: the
reader, the converter, the validator and the docs all start here.
"""

from __future__ import annotations

import functools
import hashlib
import json
import re
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import pyarrow as pa

from nuparquet.format import FORMAT_VERSION  # the docs name it


def _schema_dir() -> Path:
    packaged = resources.files("nuparquet") / "_schemas"  # wheel installs (see pyproject force-include)
    if packaged.is_dir():
        return Path(str(packaged))
    return Path(__file__).resolve().parent.parent / "schemas"  # source checkout / editable install


@dataclass(frozen=True)
class Field:
    name: str
    type: str
    doc: str = ""
    required: bool = True
    nullable: bool = False
    key: bool = False
    ref: str | None = None  # the table whose token this field (or each list element) refers to
    empty_ok: bool = False  # "" means "no reference" (prev/next)
    quaternion: bool = False  # must be finite and of unit norm
    finite: bool = False  # every value (every element of a list) must be finite: no NaN or infinity
    non_negative: bool = False  # every value (every element of a list) must be >= 0
    json_float_ok: bool = False  # the source may store it as a JSON float: kept as float64, losslessly
    empty_list_is_null: bool = False  # [] in the JSON, null in Arrow (camera_intrinsic)
    # The JSON nests the list in this shape (rows first) where the column holds it flat: camera_intrinsic is
    # [[..], [..], [..]] in calibrated_sensor.json and `fixed_size_list<float64>[9]` here, as the transforms are [16].
    json_shape: tuple[int, ...] | None = None
    # A derived column filled by a join: null where the join has no partner, which only `convert --allow-dangling`
    # lets through (a trimmed extract); the strict default keeps the column non-null (`Schema.allowing_dangling`).
    null_if_dangling: bool = False
    # The longest UTF-8 string a source field may hold: tokens (`key`, `ref`) and names that reach every row of a
    # derived dataset have one (a 40 MB scene name on a million rows is not data); None: the reader's general limit.
    max_bytes: int | None = None

    @property
    def arrow_type(self) -> pa.DataType:
        return parse_type(self.type)

    @property
    def nested_in_json(self) -> bool:
        """The JSON holds this list as rows of lists (a 3x3 intrinsic), whatever the column's layout."""
        return bool(self.json_shape) or self.type.count("fixed_size_list") == 2


@dataclass(frozen=True)
class Schema:
    name: str
    kind: str  # "table" (a nuScenes source table) or "dataset" (derived)
    version: int
    doc: str
    fields: tuple[Field, ...]
    source: str | None = None  # JSON file name, for tables
    optional: bool = False  # tables that only exist with an extension (lidarseg, panoptic)
    sort_by: tuple[str, ...] = field(default_factory=tuple)
    # Dataset-level key/value metadata written into the Parquet file footer (e.g. GeoParquet's "geo"); values
    # that are not strings are stored as their JSON text.
    metadata: dict = field(default_factory=dict)
    # Non-empty: the dataset holds further columns, which this text describes (columns that come from the input
    # itself: a CAN bus message's fields, a map record's fields), typed by inference and kept where they stand.
    extra: str = ""

    @property
    def names(self) -> list[str]:
        return [f.name for f in self.fields]

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"{self.name} has no field {name!r}")

    def allowing_dangling(self) -> "Schema":
        """This schema as `convert --allow-dangling` writes it: the `null_if_dangling` columns nullable."""
        return self.allowing_null([f.name for f in self.fields if f.null_if_dangling])

    def allowing_null(self, names) -> "Schema":
        """This schema with the fields `names` nullable (the columns a source format cannot fill: TruckScenes' log)."""
        return replace(self, fields=tuple(replace(f, nullable=True) if f.name in names else f for f in self.fields))

    def arrow_schema(self) -> pa.Schema:
        metadata = {k: v if isinstance(v, str) else json.dumps(v, sort_keys=True) for k, v in self.metadata.items()}
        return pa.schema([pa.field(f.name, f.arrow_type, nullable=f.nullable) for f in self.fields],
                         metadata=metadata or None)


_TYPES = {
    "string": pa.string(), "large_string": pa.large_string(), "binary": pa.binary(),
    "large_binary": pa.large_binary(), "bool": pa.bool_(),
    "int8": pa.int8(), "int16": pa.int16(), "int32": pa.int32(), "int64": pa.int64(),
    "uint8": pa.uint8(), "uint16": pa.uint16(), "uint32": pa.uint32(), "uint64": pa.uint64(),
    "float32": pa.float32(), "float64": pa.float64(), "date32": pa.date32(),
}
_TOKEN = re.compile(r"\s*(?:([A-Za-z_][A-Za-z0-9_]*)|(\d+)|(.))")


class _TypeParser:
    """Recursive descent over the type spelling of the schema files:

        type   := scalar | fixed_size_list<type>[n] | list<type> | large_list<type> | dictionary<type>
                | timestamp[unit] | timestamp[unit, tz] | struct<name: type, ...>
    """

    def __init__(self, spec: str):
        self.spec = spec
        self.tokens = [m.group(m.lastindex) for m in _TOKEN.finditer(spec) if m.lastindex and m.group(m.lastindex).strip()]
        self.i = 0

    def fail(self, why: str) -> ValueError:
        return ValueError(f"unknown type in schema file: {self.spec!r} ({why})")

    def peek(self) -> str | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self, expected: str | None = None) -> str:
        token = self.peek()
        if token is None or (expected is not None and token != expected):
            raise self.fail(f"expected {expected or 'more'} at token {self.i}")
        self.i += 1
        return token

    def parse(self) -> pa.DataType:
        result = self.type()
        if self.peek() is not None:
            raise self.fail(f"unexpected {self.peek()!r}")
        return result

    def type(self) -> pa.DataType:
        name = self.take()
        if name in _TYPES:
            return _TYPES[name]
        if name in ("list", "large_list", "fixed_size_list", "dictionary"):
            self.take("<")
            inner = self.type()
            self.take(">")
            if name == "fixed_size_list":
                self.take("[")
                size = self.take()
                if not size.isdigit():
                    raise self.fail("fixed_size_list needs a size")
                self.take("]")
                return pa.list_(inner, int(size))
            return {"list": pa.list_, "large_list": pa.large_list,
                    "dictionary": lambda t: pa.dictionary(pa.int32(), t)}[name](inner)
        if name == "struct":
            self.take("<")
            fields = []
            while True:
                field_name = self.take()
                self.take(":")
                fields.append(pa.field(field_name, self.type()))
                if self.peek() == ",":
                    self.take(",")
                    continue
                self.take(">")
                return pa.struct(fields)
        if name == "timestamp":
            self.take("[")
            unit = self.take()
            tz = None
            if self.peek() == ",":
                self.take(",")
                tz = ""
                while self.peek() not in ("]", None):
                    tz += self.take()
            self.take("]")
            return pa.timestamp(unit, tz=tz)
        raise self.fail(f"no type {name!r}")


def parse_type(spec: str) -> pa.DataType:
    """Arrow type from its spelling in the schema files, e.g. ``fixed_size_list<float64>[3]``,
    ``list<struct<name: string, value: uint16>>``, ``timestamp[us, UTC]``."""
    return _TypeParser(spec.strip()).parse()


def _load(path: Path) -> Schema:
    raw = json.loads(path.read_text())
    fields = tuple(Field(**(f | ({"json_shape": tuple(f["json_shape"])} if "json_shape" in f else {})))
                   for f in raw["fields"])
    return Schema(
        name=raw["name"], kind=raw["kind"], version=raw["version"], doc=raw.get("doc", ""), fields=fields,
        source=raw.get("source"), optional=raw.get("optional", False), sort_by=tuple(raw.get("sort_by", ())),
        metadata=raw.get("metadata", {}), extra=raw.get("extra", ""),
    )


@functools.cache
def table_schemas() -> dict[str, Schema]:
    """The nuScenes source tables, by name: the 13 core tables, then the optional extensions."""
    schemas = [_load(p) for p in sorted((_schema_dir() / "tables").glob("*.json"))]
    return {s.name: s for s in sorted(schemas, key=lambda s: (s.optional, s.name))}


# Other families' source tables, `schemas/<family>/tables/*.json` (TruckScenes': `sources.truckscenes.schemas`).
FAMILIES = ("nuimages", "truckscenes")


@functools.cache
def family_table_schemas(family: str) -> dict[str, Schema]:
    """The source tables of a dataset family other than nuScenes (`FAMILIES`), by name."""
    if family not in FAMILIES:
        raise KeyError(f"no source tables for {family!r} (known: {', '.join(FAMILIES)})")
    return {s.name: s for s in (_load(p) for p in sorted((_schema_dir() / family / "tables").glob("*.json")))}


@functools.cache
def dataset_schemas() -> dict[str, Schema]:
    """The derived datasets (frames, annotations, scenes, instances, sample_can_bus, points, the map), by name
    (`map/<layer>` stands for every record layer of the map expansion)."""
    paths = sorted(_schema_dir().glob("*.json")) + sorted((_schema_dir() / "map").glob("*.json"))
    return {s.name: s for s in (_load(p) for p in paths)}


def schema_for(dataset: str) -> Schema | None:
    """The schema of the dataset written as `dataset` (a manifest name): its own, or its family's for map layers
    (`map/<layer>`, `map/<lane layer>`); None for datasets typed wholly by inference (`can_bus/<message>`, extra
    source tables)."""
    schemas = dataset_schemas()
    if dataset in schemas:
        return schemas[dataset]
    if dataset.startswith("map/"):
        from nuparquet.map.layers import DICT_LAYERS

        return schemas["map/<lane layer>" if dataset.removeprefix("map/") in DICT_LAYERS else "map/<layer>"]
    if dataset.startswith("tables/"):
        return table_schemas().get(dataset.removeprefix("tables/"))
    return None


def check_columns(table: pa.Table, schema: Schema) -> None:
    """AssertionError unless `table` has every field of `schema` with its type (and, for a schema without
    `extra`, no other column): for datasets whose builder writes its own file metadata (GeoParquet)."""
    names = table.schema.names
    for f in schema.fields:
        if f.name not in names:
            raise AssertionError(f"{schema.name} lacks column {f.name}")
        if table.schema.field(f.name).type != f.arrow_type:
            raise AssertionError(f"{schema.name}.{f.name} is {table.schema.field(f.name).type}, the schema says {f.arrow_type}")
    if not schema.extra and names != schema.names:
        raise AssertionError(f"{schema.name} has columns {names}, the schema says {schema.names}")


def core_tables() -> list[str]:
    return [n for n, s in table_schemas().items() if not s.optional]


def fingerprint(schema: pa.Schema) -> str:
    """A short stable hash of an Arrow schema (names, types, nullability, and its key/value metadata other
    than pandas'/Arrow's own), for the manifest."""
    text = "\n".join(f"{f.name}:{f.type}:{f.nullable}" for f in schema)
    metadata = {k: v for k, v in (schema.metadata or {}).items() if k not in (b"pandas", b"ARROW:schema")}
    if metadata:
        text += "\n" + "\n".join(f"{k.decode()}={v.decode()}" for k, v in sorted(metadata.items()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def docs_markdown() -> str:
    """Schema documentation, generated from the schema files."""
    out = ["# nuparquet datasets", "", f"Generated from `schemas/` (format version {FORMAT_VERSION}) by "
           "`python -m nuparquet.schemas --docs`. Do not edit by hand.", ""]
    groups = [("Derived datasets", dataset_schemas()), ("Source tables (`tables/<name>`)", table_schemas())]
    groups += [(f"{family} source tables (`tables/<name>` of a {family} conversion)", family_table_schemas(family))
               for family in FAMILIES]
    for title, group in groups:
        out += [f"## {title}", ""]
        for s in group.values():
            out += [f"### `{s.name}`", "", s.doc, ""]
            if s.sort_by:
                out += [f"Rows sorted by: {', '.join(f'`{c}`' for c in s.sort_by)}.", ""]
            if s.metadata:
                out += ["File metadata: " + ", ".join(f"`{k}`" for k in s.metadata) + ".", ""]
            if s.extra:
                out += [f"Further columns: {s.extra}", ""]
            out += ["| column | type | description |", "|---|---|---|"]
            for f in s.fields:
                notes = []
                if f.nullable:
                    notes.append("nullable")
                elif f.null_if_dangling:
                    notes.append("null only with `--allow-dangling`")
                if f.ref:
                    notes.append(f"→ `{f.ref}`")
                note = f" ({', '.join(notes)})" if notes else ""
                out.append(f"| `{f.name}` | `{f.type}`{note} | {f.doc} |")
            out.append("")
    return "\n".join(out)


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description="Print or write the schema documentation.")
    parser.add_argument("--docs", metavar="PATH", help="write the Markdown documentation to PATH")
    args = parser.parse_args()
    text = docs_markdown()
    if args.docs:
        Path(args.docs).parent.mkdir(parents=True, exist_ok=True)
        Path(args.docs).write_text(text)
    else:
        print(text)
