"""Which polygons contain which points, exactly as shapely's `within` says, fast for millions of points: candidates
come from the bounding boxes of small pieces (a long thin polygon's triangles), each candidate is tested once
against the whole polygon, prepared. `MapLayers.records_on_point` / `layers_on_point` answer through here."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely import STRtree


class _Indexed:
    """Geometry with an STRtree built on first use (most queries touch a few layers)."""

    geometry: np.ndarray
    _tree: STRtree | None

    @property
    def tree(self) -> STRtree:
        if self._tree is None:
            self._tree = STRtree(self.geometry)
        return self._tree


@dataclass
class _Layer(_Indexed):
    tokens: np.ndarray  # (R,) str
    geometry: np.ndarray  # (R,) shapely (None: no geometry)
    _tree: STRtree | None = None


@dataclass
class _Parts(_Indexed):
    """Polygons of a layer as the devkit walks them one by one (drivable_area: each polygon of each record)."""

    owner: np.ndarray  # (K,) record index
    geometry: np.ndarray  # (K,)
    _tree: STRtree | None = None
    _pieces: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def pieces(self) -> tuple[np.ndarray, np.ndarray]:
        """(P,) small pieces covering the polygons and (P,) the polygon of each: where a polygon's bounding box is
        much larger than the polygon (a walkway along a road), its constrained Delaunay
        triangles, else the polygon itself. Only their bounding boxes are used, to find the few polygons a point
        may lie in: a point in a long thin polygon then meets a few triangles' boxes rather than the polygon's
        box, which holds thousands of points outside it. Built on first use."""
        if self._pieces is None:
            geometry = self.geometry
            ok = np.flatnonzero(~shapely.is_missing(geometry) & ~shapely.is_empty(geometry)) if len(geometry) \
                else np.zeros(0, np.int64)
            x_min, y_min, x_max, y_max = shapely.bounds(geometry[ok]).T if len(ok) else np.zeros((4, 0))
            box_m2 = (x_max - x_min) * (y_max - y_min)
            thin = (box_m2 > THIN_BOX_RATIO * shapely.area(geometry[ok])) & (box_m2 > THIN_MIN_BOX_M2)
            whole = ok[~thin]
            triangles, index = shapely.get_parts(shapely.constrained_delaunay_triangles(geometry[ok[thin]]),
                                                 return_index=True)
            self._pieces = (np.concatenate([geometry[whole], triangles]),
                            np.concatenate([whole, ok[thin][index]]).astype(np.int64))
        return self._pieces


# A polygon whose bounding box is this many times its area, and larger than this, is cut into triangles for point
# lookups (a 4 m x 50 m lane at 45 degrees is left whole: its box holds few points; a drivable area ~10x its box's
# fill costs more to triangulate than its extra candidates cost to test; a walkway along a road, ~50x, does not).
THIN_BOX_RATIO = 16.0
THIN_MIN_BOX_M2 = 2500.0


def _prepared(parts) -> np.ndarray:
    """The layer's polygons, prepared once (GEOS indexes their edges: a point test in O(log vertices))."""
    shapely.prepare(parts.geometry)
    return parts.geometry


def records_on_point(parts_by_layer: dict[str, _Parts], x, y) -> dict[str, np.ndarray]:
    """{layer: (N,) int64 record (`_Parts.owner`) of the first part (lowest record) strictly containing each
    point, -1 where none}."""

    x, y = np.atleast_1d(np.asarray(x, np.float64)), np.atleast_1d(np.asarray(y, np.float64))
    # Each distinct point once (annotation centres repeat: a parked car keeps its place for a whole scene).
    order = np.lexsort((y, x))
    fresh = np.r_[True, (x[order][1:] != x[order][:-1]) | (y[order][1:] != y[order][:-1])] if len(x) \
        else np.zeros(0, bool)
    of_point = np.empty(len(x), np.int64)
    of_point[order] = np.cumsum(fresh) - 1  # each point's distinct point
    ux, uy = x[order][fresh], y[order][fresh]
    # Candidates by bounding boxes: the points go in a tree and each polygon's pieces (`_Parts.pieces`: the
    # polygon, or its triangles when its box is much larger than it) ask which points their boxes hold. Each
    # (polygon, point) candidate is then tested exactly against the whole polygon, prepared (O(log vertices)
    # per test): strict interior, the devkit's `point.within`, so a point on a triangle's edge inside the
    # polygon counts and one on the polygon's own boundary does not. Testing the polygon's box alone gave
    # ~28 candidates per hit for walkways along roads (1.2M annotation centres: ~20 s).
    point_tree = STRtree(shapely.points(ux, uy))
    n, none = len(ux), np.iinfo(np.int64).max
    out = {}
    for layer, parts in parts_by_layer.items():
        found = np.full(n, none)
        pieces, piece_part = parts.pieces
        if len(pieces) and n:
            piece_i, point_i = point_tree.query(pieces)
            key = np.sort(piece_part[piece_i] * n + point_i)  # (numpy's hash-based unique is far slower)
            key = key[np.r_[True, key[1:] != key[:-1]]] if len(key) else key
            part_i, point_i = np.divmod(key, n)
            inside = shapely.contains_xy(_prepared(parts)[part_i], ux[point_i], uy[point_i])
            np.minimum.at(found, point_i[inside], parts.owner[part_i[inside]])
        out[layer] = np.where(found == none, -1, found)[of_point]
    return out
