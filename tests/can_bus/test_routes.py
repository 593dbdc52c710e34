"""`can_bus.routes.route_misalignment_m`: the devkit's Hausdorff-style distance (`list_misaligned_routes`: the largest,
over the poses, of the distance to the nearest route point), at the edges of its blocked computation: the first
pose the farthest, and the farthest pose the first of a second block of poses. Expected distances by hand."""

from __future__ import annotations

from types import SimpleNamespace

import polars as pl
import pytest

from nuparquet.can_bus.routes import _CHUNK, misaligned_routes, route_misalignment_m


def _dataset(routes: dict[str, list[tuple[float, float]]], poses: dict[str, list[tuple[float, float]]]):
    route = pl.DataFrame([(scene, i, x, y) for scene, points in routes.items() for i, (x, y) in enumerate(points)],
                         schema={"scene_name": pl.String, "point_index": pl.Int32, "x": pl.Float64, "y": pl.Float64},
                         orient="row")
    pose = pl.DataFrame({"scene_name": [s for s, xy in poses.items() for _ in xy],
                         "pos": [[x, y, 0.0] for xy in poses.values() for x, y in xy]},
                        schema={"scene_name": pl.String, "pos": pl.Array(pl.Float64, 3)})
    frames = {"can_bus/route": route, "can_bus/pose": pose}
    return SimpleNamespace(root="ds", datasets=frames, scan=lambda name: frames[name].lazy())


def test_the_first_pose_and_the_first_pose_of_a_second_block_count():
    route = [(10.0 * i, 0.0) for i in range(11)]  # a straight road along x, a point every 10 m
    on_road = [(10.0 * (i % 11), 0.25) for i in range(_CHUNK + 5)]  # 0.25 m from a route point
    first_far = [(20.0, 7.0), *on_road[:3]]  # the farthest pose is the scene's first: 7 m
    block_far = on_road[:_CHUNK] + [(30.0, 6.0)] + on_road[_CHUNK:]  # the farthest is row _CHUNK: 6 m
    ds = _dataset({"scene-0001": route, "scene-0002": route, "scene-0003": route},
                  {"scene-0001": first_far, "scene-0002": block_far, "scene-0003": on_road})
    got = route_misalignment_m(ds)
    assert got["scene_name"].to_list() == ["scene-0001", "scene-0002", "scene-0003"]
    assert got["misalignment_m"].to_list() == pytest.approx([7.0, 6.0, 0.25], abs=1e-12)
    assert misaligned_routes(ds, 6.5) == ["scene-0001"]
    assert misaligned_routes(ds, 5.0) == ["scene-0001", "scene-0002"]
    assert misaligned_routes(ds, 0.25) == ["scene-0001", "scene-0002"]  # more than the threshold, not equal to it


def test_a_scene_with_poses_but_no_route_is_left_out():
    """The devkit's list_misaligned_routes only measures scenes that have a route: a scene whose route file is
    missing (its poses alone) is not in the table, and the others are measured as before."""
    route = [(0.0, 0.0), (10.0, 0.0)]
    ds = _dataset({"scene-0002": route}, {"scene-0001": [(5.0, 3.0)], "scene-0002": [(10.0, 2.0), (0.0, 0.5)]})
    got = route_misalignment_m(ds)
    assert got["scene_name"].to_list() == ["scene-0002"]
    assert got["misalignment_m"].to_list() == pytest.approx([2.0], abs=1e-12)
