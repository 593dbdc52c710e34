"""DuckDB's Arrow output cast to the schema's types: variable lists to fixed-size lists (every length checked),
[] intrinsics to null, required fields non-null; a problem names each record that does not fit."""

from __future__ import annotations

import pyarrow as pa
import pyarrow.compute as pc

from nuparquet.problems import Problem
from nuparquet.schemas import Schema


def to_schema_types(raw: pa.Table, schema: Schema, file: str, float_fields: list[str]) -> tuple[pa.Table, list[Problem]]:
    """Cast DuckDB's Arrow output to the schema's types: variable lists to fixed-size lists (checking
    lengths), [] intrinsics to null, required fields non-null. Unknown fields are kept as read."""
    tokens = raw.column("token") if "token" in raw.column_names else None
    problems: list[Problem] = []

    def record_problems(mask: pa.ChunkedArray, message: str) -> None:
        indices = pc.indices_nonzero(mask.combine_chunks() if isinstance(mask, pa.ChunkedArray) else mask)
        for idx in indices.to_pylist()[:50]:
            token = tokens[idx].as_py() if tokens is not None else None
            problems.append(Problem(file, message, idx, token))

    columns = {}
    for f in schema.fields:
        if f.name not in raw.column_names:
            columns[f.name] = pa.nulls(raw.num_rows, f.arrow_type)
            continue
        col = raw.column(f.name)
        if f.required and col.null_count:
            record_problems(pc.is_null(col), f"required field {f.name!r} is missing or null")
            continue
        target = f.arrow_type
        if f.name in float_fields:
            target = pa.float64()
        if pa.types.is_fixed_size_list(target):
            nested = _nested_type(f.json_shape, target) if f.json_shape else target
            col, bad = _fixed_size(col, nested, empty_is_null=f.empty_list_is_null)
            if bad is None and nested is not target:  # [[..], [..]] in the JSON, flat in the column
                col = _flattened(col, target)
            if bad is not None:
                n = nested.list_size
                shape = f"{n}x{nested.value_type.list_size}" if pa.types.is_fixed_size_list(nested.value_type) else n
                record_problems(bad, f"field {f.name!r} must have {shape} numbers" + (" or be []" if f.empty_list_is_null else ""))
                continue
        else:
            col = col.cast(target)
        columns[f.name] = col
    for name in raw.column_names:
        if name not in columns:
            columns[name] = raw.column(name)
    if problems:
        return raw, problems
    order = schema.names + [n for n in raw.column_names if n not in schema.names]
    nullable = {f.name: f.nullable for f in schema.fields}
    fields = [pa.field(n, columns[n].type, nullable=nullable.get(n, True)) for n in order]
    return pa.table([columns[n] for n in order], schema=pa.schema(fields)), []


def _nested_type(shape: tuple[int, ...], flat: pa.FixedSizeListType) -> pa.DataType:
    """The nested fixed-size list type a field of `json_shape` (rows, columns) has in the JSON."""
    rows, columns = shape
    if rows * columns != flat.list_size:
        raise ValueError(f"json_shape {shape} does not hold {flat.list_size} values")
    return pa.list_(pa.list_(flat.value_type, columns), rows)


def _flattened(col: pa.ChunkedArray, flat: pa.FixedSizeListType) -> pa.ChunkedArray:
    """Nested fixed-size lists (rows of columns) -> one flat fixed-size list per row, row-major; nulls kept."""
    arr = col.combine_chunks()
    values = pc.list_flatten(pc.list_flatten(arr)) if arr.null_count == 0 else None
    if values is None:  # list_flatten skips null rows: spread the valid rows back out
        keep = pc.is_valid(arr)
        dense = pa.FixedSizeListArray.from_arrays(pc.list_flatten(pc.list_flatten(arr.filter(keep))), flat.list_size)
        positions = pc.subtract(pc.cumulative_sum(keep.cast(pa.int64())), 1)
        taken = dense.take(pc.if_else(keep, positions, 0)) if len(dense) else pa.nulls(len(arr), flat)
        return pa.chunked_array([pc.if_else(keep, taken, pa.scalar(None, flat))])
    return pa.chunked_array([pa.FixedSizeListArray.from_arrays(values.cast(flat.value_type), flat.list_size)])


def _fixed_size(col: pa.ChunkedArray, target: pa.FixedSizeListType, *, empty_is_null: bool):
    """Variable list -> fixed_size_list, checking every length. Returns (array, bad-rows mask or None)."""
    arr = col.combine_chunks()
    n = target.list_size
    lengths = pc.list_value_length(arr)
    is_empty = pc.equal(lengths, 0)
    inner_type = target.value_type
    ok = pc.equal(lengths, n)
    if pa.types.is_fixed_size_list(inner_type):
        inner_lengths = pc.list_value_length(pc.list_flatten(arr))
        inner_ok = pc.all(pc.equal(inner_lengths, inner_type.list_size)).as_py() is not False
        if not inner_ok:  # find the rows holding a bad inner list
            parents = pc.list_parent_indices(arr)
            bad_parent = pc.filter(parents, pc.not_equal(inner_lengths, inner_type.list_size))
            bad = pc.is_in(pa.array(range(len(arr))), value_set=pc.unique(bad_parent))
            return None, bad
    if empty_is_null:
        ok = pc.or_(ok, is_empty)
    if not pc.all(ok).as_py():
        return None, pc.invert(ok)
    values = pc.list_flatten(arr)
    if pa.types.is_fixed_size_list(inner_type):
        values = pa.FixedSizeListArray.from_arrays(pc.list_flatten(values).cast(pa.float64()), inner_type.list_size)
    else:
        values = values.cast(inner_type)
    if empty_is_null and pc.any(is_empty).as_py():
        # `values` holds only the non-empty rows: spread them back out, with nulls where the list was [].
        keep = pc.invert(is_empty)
        if not pc.any(keep).as_py():
            return pa.chunked_array([pa.nulls(len(arr), target)]), None
        dense = pa.FixedSizeListArray.from_arrays(values, n)
        positions = pc.subtract(pc.cumulative_sum(keep.cast(pa.int64())), 1)
        taken = dense.take(pc.if_else(keep, positions, 0))
        return pa.chunked_array([pc.if_else(keep, taken, pa.scalar(None, taken.type))]), None
    return pa.chunked_array([pa.FixedSizeListArray.from_arrays(values, n)]), None
