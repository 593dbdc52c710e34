"""The ten JSON tables of a nuImages version folder (`nuimages.NuImages`' tables), read exactly and checked.

nuImages is not nuScenes-shaped: no scene, instance, sample_annotation, visibility or map table; a `sample` is one
annotated keyframe image (`key_camera_token`) with the non-keyframe images around it on a sample_data prev/next
chain; `object_ann` holds 2D boxes and instance masks, `surface_ann` surface masks, both as COCO RLE whose
`counts` are base64 (`nuparquet.rle`); `calibrated_sensor` has `camera_distortion`; `ego_pose` has rates and speed.

Each table is read as Python's json reads it (the devkit's reader) and typed by inference, exactly reversible
(`sources.json_records`: `export-json` writes it back, byte for byte in the layouts `sources.json_layout` knows).
Then its columns are held against `schemas/nuimages/tables/<name>.json` (a field missing, null or of another JSON
type is refused, naming the file, the field and the first record), the keys and references are checked as for
nuScenes (`sources.integrity`, driven by those schemas), and every mask must decode exactly: base64, a
pycocotools RLE string, runs covering exactly its size, the size of its image.
"""

from __future__ import annotations

import base64
import binascii
import json
from pathlib import Path
from typing import Callable

import numpy as np
import polars as pl
import pyarrow as pa

from nuparquet import rle
from nuparquet.problems import MAX_REPORTED, Problem, echo
from nuparquet.schemas import Field, Schema, family_table_schemas
from nuparquet.sources.integrity import check_integrity
from nuparquet.sources.tables import ReadResult, SourceTable, read_extra_table, version_dir

FAMILY = "nuimages"
MASK_TABLES = ("object_ann", "surface_ann")
# Fields held as JSON text in tables/ (objects, nested lists): the derived datasets parse them.
JSON_FIELDS = {("object_ann", "mask"), ("surface_ann", "mask"), ("calibrated_sensor", "camera_intrinsic")}


def schemas() -> dict[str, Schema]:
    return family_table_schemas(FAMILY)


def looks_like(folder: Path) -> bool:
    """A version folder of nuImages: its annotation tables, and no nuScenes scene or sample_annotation table."""
    return (all((folder / f"{name}.json").is_file() for name in ("object_ann", "surface_ann", "sample_data"))
            and not (folder / "scene.json").exists() and not (folder / "sample_annotation.json").exists())


def read_nuimages_tables(dataroot: Path | str, version: str, *, on_table: Callable[[str], None] | None = None,
                         finish: Callable[[SourceTable], None] | None = None) -> ReadResult:
    """Every JSON table of `dataroot/version`: the ten nuImages tables (a missing one is a problem) and any other
    JSON file of the folder (typed by inference as well). Problems are collected, not raised; `finish(table)` runs
    on each table read without problems (as `sources.tables.read_tables`)."""
    folder = version_dir(dataroot, version)
    tables: dict[str, SourceTable] = {}
    problems: list[Problem] = []
    files: dict[str, dict] = {}
    declared = schemas()
    for name, schema in declared.items():
        if on_table:
            on_table(name)
        path = folder / schema.source
        if not path.is_file():
            problems.append(Problem(schema.source, f"table {name} is missing (expected {path})"))
            continue
        files[schema.source] = {"bytes": path.stat().st_size, "mtime": path.stat().st_mtime}
        table, found = read_extra_table(path)
        found = found or (type_problems(table, schema) if table is not None else [])
        problems += found
        if table is not None and not found:
            if finish is not None:
                finish(table)
            tables[name] = table
    for path in sorted(p for p in folder.glob("*.json") if p.stem not in declared):
        if on_table:
            on_table(path.stem)
        files[path.name] = {"bytes": path.stat().st_size, "mtime": path.stat().st_mtime}
        table, found = read_extra_table(path)
        problems += found
        if table is not None:
            if finish is not None:
                finish(table)
            tables[table.name] = table
    return ReadResult(tables, problems, files)


def type_problems(source: SourceTable, schema: Schema) -> list[Problem]:
    """The declared fields of one table typed by inference that its columns do not hold as declared: each named
    with the first record at fault (also TruckScenes' ego-motion tables, `sources.truckscenes`)."""
    table, file = source.table, schema.source
    json_fields = set(source.inferred["json_fields"]) if source.inferred else set()
    problems = []
    if table.num_rows == 0:
        return problems
    for f in schema.fields:
        if f.name not in table.column_names:
            problems.append(Problem(file, f"field {f.name!r} is missing (the first record has "
                                          f"{', '.join(source.key_order)})", 0))
            continue
        column = table.column(f.name).combine_chunks()
        nulls = column.is_null().to_numpy(zero_copy_only=False)
        if not f.nullable and nulls.any():
            problems.append(_at(file, table, int(np.argmax(nulls)), f"field {f.name!r} is null"))
            continue
        if column.null_count == len(column):
            continue
        why = _misfit(column, f, (schema.name, f.name) in JSON_FIELDS, f.name in json_fields)
        if why is not None:
            index, message = why
            problems.append(_at(file, table, index, f"field {f.name!r} {message}"))
    return problems


def _at(file: str, table: pa.Table, index: int | None, message: str) -> Problem:
    token = table.column("token")[index].as_py() if index is not None and "token" in table.column_names else None
    return Problem(file, message, index, token if isinstance(token, str) else None)


_WORDS = {"string": "a string", "int64": "an integer", "float64": "a number", "bool": "a boolean",
          "list<string>": "a list of strings", "list<float64>": "a list of numbers"}


def _misfit(column: pa.Array, f: Field, json_text: bool, is_json: bool) -> tuple[int | None, str] | None:
    """(record index or None, what is wrong) when the inferred `column` does not hold field `f` as declared."""
    got = column.type
    if json_text:  # an object or nested lists in the JSON: inference keeps it as JSON text
        return None if is_json else (None, f"must hold {'an object' if f.name == 'mask' else 'a 3x3 list of numbers'} "
                                           f"in every record, but holds {_type_word(got)}")
    if f.type in ("string", "int64", "bool"):
        return None if got == f.arrow_type else (None, f"must be {_WORDS[f.type]}, but holds {_type_word(got)}")
    if f.type == "float64":
        return None if got in (pa.float64(), pa.int64()) else (None, f"must be a number, but holds {_type_word(got)}")
    lengths = _lengths(column)
    if lengths is None:
        return None, f"must be {_list_word(f)}, but holds {_type_word(got)}"
    element = got.value_type
    if f.type == "list<string>":
        if element == pa.string() or (lengths == 0).all():  # all [] infers as a list of numbers
            return None
        return None, f"must be a list of strings, but holds {_type_word(got)}"
    wanted = f.arrow_type
    numbers = (pa.int64(),) if wanted.value_type == pa.int64() else (pa.float64(), pa.int64())
    if element not in numbers:
        return None, f"must be {_list_word(f)}, but holds {_type_word(got)}"
    if pa.types.is_fixed_size_list(wanted) and (lengths != wanted.list_size).any():
        index = int(np.argmax(lengths != wanted.list_size))
        return index, f"must have {wanted.list_size} numbers, has {int(lengths[index])}"
    return None


def _lengths(column: pa.Array) -> np.ndarray | None:
    if pa.types.is_fixed_size_list(column.type):
        return np.full(len(column), column.type.list_size)
    if pa.types.is_list(column.type):
        import pyarrow.compute as pc

        return pc.list_value_length(column).fill_null(0).to_numpy()
    return None


def _list_word(f: Field) -> str:
    t = f.arrow_type
    if pa.types.is_fixed_size_list(t):
        return f"a list of {t.list_size} {'integers' if t.value_type == pa.int64() else 'numbers'}"
    return _WORDS[f.type]


def _type_word(t: pa.DataType) -> str:
    if pa.types.is_string(t):
        return "strings (or an object in some records)"
    if pa.types.is_list(t) or pa.types.is_fixed_size_list(t):
        return f"lists of {_type_word(t.value_type).split(' (')[0]}"
    return {pa.int64(): "integers", pa.float64(): "numbers with fractions", pa.bool_(): "booleans",
            pa.null(): "null"}.get(t, str(t))


def check_nuimages(tables: dict[str, pl.DataFrame], *, references: bool = True) -> list[Problem]:
    """Every problem across the parsed nuImages tables: unique tokens, references, quaternions (as for nuScenes,
    from the schemas), 3x3 intrinsics, and masks that decode exactly to their image's size."""
    problems = check_integrity(tables, references=references, schemas=schemas())
    if "calibrated_sensor" in tables:
        problems += _intrinsic_problems(tables["calibrated_sensor"])
    images = tables.get("sample_data")
    for name in MASK_TABLES:
        if name in tables:
            problems += mask_facts(tables[name], f"{name}.json", images)[1]
    return problems


def intrinsics(frame: pl.DataFrame) -> list[list[float] | None]:
    """calibrated_sensor's `camera_intrinsic` JSON texts as 9 numbers each (None where not a 3x3 list)."""
    out = []
    for text in frame["camera_intrinsic"].to_list():
        value = json.loads(text) if text is not None else None
        ok = (isinstance(value, list) and len(value) == 3 and all(isinstance(r, list) and len(r) == 3 for r in value)
              and all(type(x) in (int, float) for r in value for x in r))
        out.append([float(x) for r in value for x in r] if ok else None)
    return out


def _intrinsic_problems(frame: pl.DataFrame) -> list[Problem]:
    bad = [i for i, v in enumerate(intrinsics(frame)) if v is None]
    tokens = frame["token"].to_list()
    return [Problem("calibrated_sensor.json", "field 'camera_intrinsic' must be a 3x3 list of numbers, got "
                    + echo(frame["camera_intrinsic"][i], quote=False), i, tokens[i]) for i in bad[:MAX_REPORTED]]


def mask_facts(frame: pl.DataFrame, file: str, images: pl.DataFrame | None = None
               ) -> tuple[pl.DataFrame, list[Problem]]:
    """(mask_height, mask_width, mask_counts, mask_area per record of a mask table, the problems): each `mask` JSON
    text must be null or `{"size": [h, w], "counts": base64 text}` whose runs cover exactly h x w pixels, and h x w
    must be its image's height x width (`images`: sample_data)."""
    texts = frame["mask"].to_list()
    n = len(texts)
    heights, widths = np.zeros(n, np.int64), np.zeros(n, np.int64)
    counts: list[str | None] = [None] * n
    raw: list[bytes] = [b""] * n
    problems: list[Problem] = []
    tokens = frame["token"].to_list()
    for i, text in enumerate(texts):
        if text is None:
            continue
        mask = json.loads(text)
        why = _mask_shape(mask)
        if why is None:
            try:
                raw[i] = base64.b64decode(mask["counts"])  # as the devkit's mask_decode
            except (binascii.Error, ValueError) as exc:
                why = f"its counts are not base64 ({exc})"
        if why is not None:
            problems.append(Problem(file, f"field 'mask' cannot be decoded: {why}", i, tokens[i]))
            continue
        heights[i], widths[i] = mask["size"]
        counts[i] = mask["counts"]
    present = np.array([c is not None for c in counts], bool)
    areas, bad = rle.summarise(raw, np.where(present, heights, 0), np.where(present, widths, 0))
    for i in np.flatnonzero(bad & present)[:MAX_REPORTED].tolist():
        try:
            rle.counts_of({"size": [int(heights[i]), int(widths[i])], "counts": counts[i]})
            why = "it does not decode"  # (summarise and counts_of agree; kept for safety)
        except rle.MaskError as exc:
            why = str(exc)
        problems.append(Problem(file, f"field 'mask' cannot be decoded: {why}", i, tokens[i]))
    facts = pl.DataFrame({"mask_height": pl.Series(np.where(present, heights, 0), dtype=pl.Int64),
                          "mask_width": pl.Series(np.where(present, widths, 0), dtype=pl.Int64),
                          "mask_counts": pl.Series(counts, dtype=pl.String),
                          "mask_area": pl.Series(areas, dtype=pl.Int64)})
    facts = facts.with_columns(pl.when(pl.Series(present)).then(pl.col(c)).otherwise(None)
                               for c in ("mask_height", "mask_width", "mask_area"))
    if images is not None and "sample_data_token" in frame.columns:
        problems += _size_problems(frame, facts, images, file)
    return facts, problems


def _mask_shape(mask) -> str | None:
    if not isinstance(mask, dict):
        return f"expected an object with size and counts, got {echo(json.dumps(mask), quote=False)}"
    size = mask.get("size")
    if not (isinstance(size, list) and len(size) == 2 and all(type(v) is int and v >= 0 for v in size)):
        return f"its size must be [height, width] in pixels, got {echo(json.dumps(size), quote=False)}"
    if not isinstance(mask.get("counts"), str):
        return f"its counts must be a base64 string, got {echo(json.dumps(mask.get('counts')), quote=False)}"
    return None


def _size_problems(frame: pl.DataFrame, facts: pl.DataFrame, images: pl.DataFrame, file: str) -> list[Problem]:
    """Masks whose size is not their image's (the devkit overlays and indexes masks on the image: it would fail)."""
    joined = (pl.concat([frame.select("token", "sample_data_token").with_row_index("_idx"), facts], how="horizontal")
              .join(images.select(pl.col("token").alias("sample_data_token"), "height", "width"),
                    on="sample_data_token", how="inner")
              .filter(pl.col("mask_height").is_not_null()
                      & ((pl.col("mask_height") != pl.col("height")) | (pl.col("mask_width") != pl.col("width"))))
              .sort("_idx"))
    return [Problem(file, f"field 'mask' has size [{r['mask_height']}, {r['mask_width']}] but its image "
                          f"{r['sample_data_token']} is {r['height']} x {r['width']} (height x width)", r["_idx"],
                    r["token"]) for r in joined.head(MAX_REPORTED).iter_rows(named=True)]
