"""`can_bus.files.SceneRows`: a scene's rows found by the row groups' `scene_name` statistics, a group that holds
several scenes filtered to the one asked for, a group of only that scene read whole, in file order."""

from __future__ import annotations

import pyarrow as pa
import pyarrow.parquet as pq

from nuparquet.can_bus.files import SceneRows


def test_a_scenes_rows_come_from_its_row_groups_and_shared_groups_are_filtered(tmp_path):
    path = tmp_path / "part-0.parquet"
    table = pa.table({"scene_name": ["scene-a", "scene-b", "scene-a", "scene-c", "scene-c", "scene-d"],
                      "utime": [1, 2, 3, 4, 5, 6]})
    with pq.ParquetWriter(path, table.schema) as writer:  # groups: {a, b, a}, {c, c}, {d}
        writer.write_table(table.slice(0, 3))
        writer.write_table(table.slice(3, 2))
        writer.write_table(table.slice(5, 1))
    rows = SceneRows([str(path)])
    assert [(low, high) for _, _, low, high in rows.groups] == [("scene-a", "scene-b"), ("scene-c", "scene-c"),
                                                                ("scene-d", "scene-d")]
    assert rows.table("scene-a", ["utime"]).column("utime").to_pylist() == [1, 3]  # b's row left out
    assert rows.table("scene-b", ["utime"]).column("utime").to_pylist() == [2]
    assert rows.table("scene-c", ["utime"]).column("utime").to_pylist() == [4, 5]
    assert rows.table("scene-e", ["utime"]).num_rows == 0
