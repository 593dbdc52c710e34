"""Sentinel values are not data: Lyft Level 5 writes num_lidar_pts = -1 where it did not count points."""

from __future__ import annotations

import polars as pl
import pytest

from nuparquet.queries import points_per_box


def test_negative_point_counts_are_left_out_of_the_statistics():
    boxes = pl.LazyFrame({"category_name": ["car"] * 5, "num_lidar_pts": [-1, 0, 5, 10, -1],
                          "num_radar_pts": [-1, -1, -1, -1, -1]})
    row = points_per_box(boxes).collect().row(0, named=True)
    assert row["num_boxes"] == 5  # every box is counted
    assert row["lidar_mean"] == pytest.approx(5.0) and row["lidar_min"] == 0 and row["lidar_max"] == 10
    assert row["lidar_zero_share"] == pytest.approx(1 / 3)  # of the three counted boxes
    assert row["lidar_p50"] == pytest.approx(5.0)
    assert row["radar_mean"] is None and row["radar_zero_share"] is None  # nothing counted
