"""`MapLayers.records_on_point` / `layers_on_point` on hand-built layers: long thin polygons are cut into
triangles only to find candidates, so the answer must stay the devkit's `point.within(polygon)` for the first
record in file order, exactly at the places the cutting could get wrong: points on the triangles' inner edges
(inside the polygon: found), on the polygon's own boundary and its hole's (outside: not found), repeated points,
and overlapping records. Expectations come from shapely's scalar `within`, one point and polygon at a time."""

from __future__ import annotations

import numpy as np
import shapely

from nuparquet.map.lookup import THIN_BOX_RATIO, _Layer, _Parts
from nuparquet.map.queries import MapLayers


def _strip(x0: float, y0: float, length: float, width: float, angle_rad: float, *, bends: int = 6) -> shapely.Polygon:
    """A long zig-zagging strip (a walkway along a road): bounding box far larger than the polygon."""
    t = np.linspace(0.0, length, bends + 1)
    centre = np.c_[x0 + t * np.cos(angle_rad), y0 + t * np.sin(angle_rad)]
    centre[1::2] += 6.0 * np.array([-np.sin(angle_rad), np.cos(angle_rad)])
    normal = np.array([-np.sin(angle_rad), np.cos(angle_rad)]) * width / 2
    return shapely.Polygon(np.r_[centre + normal, (centre - normal)[::-1]])


def _map(polygons: list) -> MapLayers:
    geometry = np.array(polygons, dtype=object)
    tokens = np.array([f"p{i}" for i in range(len(polygons))], dtype=object)
    return MapLayers("here", {"walkway": _Layer(tokens, geometry)},
                     {"walkway": _Parts(np.arange(len(polygons)), geometry)})


def _expected(polygons, x, y) -> np.ndarray:
    out = np.full(len(x), -1)
    for i, (px, py) in enumerate(zip(x, y)):
        point = shapely.Point(px, py)
        out[i] = next((k for k, polygon in enumerate(polygons) if polygon is not None and point.within(polygon)), -1)
    return out


def test_points_on_inner_triangle_edges_boundaries_and_holes_get_the_devkit_answer():
    with_hole = shapely.Polygon(shapely.box(300.0, 0.0, 700.0, 20.0).exterior.coords,
                                [shapely.box(400.0, 5.0, 420.0, 15.0).exterior.coords])
    polygons = [_strip(0.0, 0.0, 400.0, 4.0, np.pi / 4), _strip(10.0, 0.0, 380.0, 5.0, np.pi / 4 + 0.05),
                with_hole, None, shapely.box(250.0, 250.0, 260.0, 260.0)]
    m = _map(polygons)
    pieces, owner = m.parts["walkway"].pieces
    assert len(pieces) > len(polygons) and set(owner) == {0, 1, 2, 4}  # the strips and the hole's box were cut
    triangles = pieces[len(np.flatnonzero(owner == 4)):]
    # inner edges of the triangulation: midpoints of triangle edges strictly inside their polygon
    edges = shapely.get_coordinates(shapely.boundary(triangles)).reshape(-1, 2)
    midpoints = (edges[:-1] + edges[1:]) / 2
    # the polygons' own boundaries (vertices and edge midpoints, the hole's too): never inside
    rings = np.concatenate([shapely.get_coordinates(shapely.boundary(p)) for p in polygons if p is not None])
    rng = np.random.default_rng(0)
    anywhere = rng.uniform([-10.0, -10.0], [720.0, 300.0], (4000, 2))
    points = np.r_[midpoints, rings, (rings[:-1] + rings[1:]) / 2, anywhere, anywhere[:50]]  # repeats too
    x, y = points[:, 0], points[:, 1]
    expected = _expected(polygons, x, y)
    assert (expected >= 0).sum() > 200 and (expected == 1).any() and (expected == 2).any()
    on_inner_edges = expected[:len(midpoints)] >= 0
    assert on_inner_edges.sum() > 50  # the cut lines' own points are reached
    found = m.records_on_point(x, y, ["walkway"])["walkway"]
    np.testing.assert_array_equal(found, expected)
    tokens = m.layers_on_point(x, y, ["walkway"])["walkway"]
    np.testing.assert_array_equal(tokens, np.where(expected >= 0, np.array([f"p{k}" for k in expected]), ""))


def test_only_polygons_much_larger_than_their_box_fill_are_cut():
    square = shapely.box(0.0, 0.0, 100.0, 100.0)  # box = polygon: kept whole
    small_diagonal = _strip(0.0, 0.0, 40.0, 0.5, np.pi / 4, bends=1)  # thin, but its box is small
    long_diagonal = _strip(0.0, 0.0, 400.0, 2.0, np.pi / 4, bends=1)
    box_area = lambda g: np.prod(np.diff(np.reshape(g.bounds, (2, 2)), axis=0))  # noqa: E731
    assert box_area(small_diagonal) > THIN_BOX_RATIO * small_diagonal.area
    m = _map([square, small_diagonal, long_diagonal])
    pieces, owner = m.parts["walkway"].pieces
    assert list(owner[:2]) == [0, 1] and pieces[0] is square and (owner[2:] == 2).all() and len(owner) > 3


def test_no_points_no_candidates_and_missing_geometry():
    m = _map([None, shapely.box(0.0, 0.0, 1.0, 1.0)])
    assert m.records_on_point([], [], ["walkway"])["walkway"].shape == (0,)
    np.testing.assert_array_equal(m.records_on_point([5.0, 0.5, 1.0], [5.0, 0.5, 0.5], ["walkway"])["walkway"],
                                  [-1, 1, -1])
