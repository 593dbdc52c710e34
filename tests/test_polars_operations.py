"""Every dataset of a conversion takes the common polars operations (issue 24): a nested fixed-size list column
(the 3x3 `camera_intrinsic` of format 1, a fixed-size list of strings typed by inference) made
`scan("frames").collect().reverse()` a Rust panic. Matrices are stored flat (`[9]`, `[16]`), lists of strings as
variable lists."""

from __future__ import annotations

import polars as pl
import pytest

import nuparquet

OPERATIONS = {
    "reverse": lambda df: df.reverse(),
    "lazy reverse": lambda df: df.lazy().reverse().collect(),
    "sort": lambda df: df.with_row_index("_i").sort("_i", descending=True),
    "unique": lambda df: df.with_row_index("_i").unique(maintain_order=True),
    "join": lambda df: df.with_row_index("_i").join(df.with_row_index("_i").select("_i"), on="_i"),
    "filter": lambda df: df.with_row_index("_i").filter(pl.col("_i") % 2 == 0),
    "concat": lambda df: pl.concat([df, df]),
    "shift": lambda df: df.shift(1),
    "to_pandas": lambda df: df.to_pandas(),
}
OUTPUTS = ["synth_out", "map_out", "lidarseg_out", "wild_can_out", "lyft_rig_out", "irregular_out", "extract_points_out"]


def _nested(schema: pl.Schema) -> list[str]:
    """Columns that are fixed-size lists of something other than numbers (what polars cannot reverse)."""
    return [name for name, dtype in schema.items()
            if isinstance(dtype, pl.Array) and not dtype.inner.is_numeric()]


@pytest.mark.parametrize("output", OUTPUTS)
def test_every_dataset_takes_the_common_polars_operations(output, request):
    ds = nuparquet.open(request.getfixturevalue(output))
    checked = 0
    for name in ds.datasets:
        df = ds.scan(name).head(400).collect()  # the panic does not depend on the row count
        assert _nested(df.schema) == [], f"{name} holds a fixed-size list of non-numbers"
        for operation, run in OPERATIONS.items():
            result = run(df)
            expected = 2 * df.height if operation == "concat" else df.height
            assert len(result) in (expected, (df.height + 1) // 2), f"{name}: {operation}"
        checked += 1
    assert checked == len(ds.datasets) > 10


def test_matrices_are_flat_row_major_lists_of_numbers(synth_out):
    ds = nuparquet.open(synth_out)
    frames = ds.scan("frames").collect_schema()
    assert frames["camera_intrinsic"] == pl.Array(pl.Float64, 9)
    assert frames["global_from_ego"] == pl.Array(pl.Float64, 16)
    assert ds.scan("tables/calibrated_sensor").collect_schema()["camera_intrinsic"] == pl.Array(pl.Float64, 9)
    camera = ds.scan("frames").filter(pl.col("camera_intrinsic").is_not_null()).head(1).collect()
    k = camera["camera_intrinsic"][0].to_list()
    # row-major: fx, 0, cx / 0, fy, cy / 0, 0, 1
    assert k[1] == k[3] == k[6] == k[7] == 0.0 and k[8] == 1.0 and k[0] > 100 and k[2] > 100


def test_the_format_version_is_two():
    from nuparquet.format import FORMAT_VERSION

    assert FORMAT_VERSION == 2
