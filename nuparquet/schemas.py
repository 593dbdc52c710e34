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
from dataclasses import dataclass, field
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
    json_float_ok: bool = False  # the source may store it as a JSON float: kept as float64, losslessly
    empty_list_is_null: bool = False  # [] in the JSON, null in Arrow (camera_intrinsic)

    @property
    def arrow_type(self) -> pa.DataType:
        return parse_type(self.type)


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

    @property
    def names(self) -> list[str]:
        return [f.name for f in self.fields]

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"{self.name} has no field {name!r}")

    def arrow_schema(self) -> pa.Schema:
        return pa.schema([pa.field(f.name, f.arrow_type, nullable=f.nullable) for f in self.fields])


_TYPES = {
    "string": pa.string(), "bool": pa.bool_(), "int8": pa.int8(), "int16": pa.int16(),
    "int32": pa.int32(), "int64": pa.int64(), "float32": pa.float32(), "float64": pa.float64(),
    "date32": pa.date32(),
}


def parse_type(spec: str) -> pa.DataType:
    """Arrow type from its spelling in the schema files, e.g. ``fixed_size_list<float64>[3]``."""
    spec = spec.strip()
    if spec in _TYPES:
        return _TYPES[spec]
    if m := re.fullmatch(r"fixed_size_list<(.+)>\[(\d+)\]", spec):
        return pa.list_(parse_type(m[1]), int(m[2]))
    if m := re.fullmatch(r"list<(.+)>", spec):
        return pa.list_(parse_type(m[1]))
    if m := re.fullmatch(r"dictionary<(.+)>", spec):
        return pa.dictionary(pa.int32(), parse_type(m[1]))
    if m := re.fullmatch(r"timestamp\[(\w+)(?:,\s*(.+))?\]", spec):
        return pa.timestamp(m[1], tz=m[2])
    raise ValueError(f"unknown type in schema file: {spec!r}")


def _load(path: Path) -> Schema:
    raw = json.loads(path.read_text())
    fields = tuple(Field(**f) for f in raw["fields"])
    return Schema(
        name=raw["name"], kind=raw["kind"], version=raw["version"], doc=raw.get("doc", ""), fields=fields,
        source=raw.get("source"), optional=raw.get("optional", False), sort_by=tuple(raw.get("sort_by", ())),
    )


@functools.cache
def table_schemas() -> dict[str, Schema]:
    """The nuScenes source tables, by name: the 13 core tables, then the optional extensions."""
    schemas = [_load(p) for p in sorted((_schema_dir() / "tables").glob("*.json"))]
    return {s.name: s for s in sorted(schemas, key=lambda s: (s.optional, s.name))}


@functools.cache
def dataset_schemas() -> dict[str, Schema]:
    """The derived datasets (frames, annotations, scenes, instances), by name."""
    return {s.name: s for s in (_load(p) for p in sorted(_schema_dir().glob("*.json")))}


def core_tables() -> list[str]:
    return [n for n, s in table_schemas().items() if not s.optional]


def fingerprint(schema: pa.Schema) -> str:
    """A short stable hash of an Arrow schema (names, types, nullability), for the manifest."""
    text = "\n".join(f"{f.name}:{f.type}:{f.nullable}" for f in schema)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def docs_markdown() -> str:
    """Schema documentation, generated from the schema files."""
    out = ["# nuparquet datasets", "", f"Generated from `schemas/` (format version {FORMAT_VERSION}) by "
           "`python -m nuparquet.schemas --docs`. Do not edit by hand.", ""]
    for title, group in (("Derived datasets", dataset_schemas()), ("Source tables (`tables/<name>`)", table_schemas())):
        out += [f"## {title}", ""]
        for s in group.values():
            out += [f"### `{s.name}`", "", s.doc, ""]
            if s.sort_by:
                out += [f"Rows sorted by: {', '.join(f'`{c}`' for c in s.sort_by)}.", ""]
            out += ["| column | type | description |", "|---|---|---|"]
            for f in s.fields:
                notes = []
                if f.nullable:
                    notes.append("nullable")
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
