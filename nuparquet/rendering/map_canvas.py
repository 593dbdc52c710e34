"""Map geometry into pixels (OpenCV): polygons filled ring by ring with their holes, line strings, both opaque or
blended; a north-up canvas over a rectangle of a map (`MapCanvas`) for the map pictures of `map_views`. The bird's-eye
view's raster (`bev.MapRaster`) draws with the same functions.

Polygons are filled one ring per call, exterior then its holes: OpenCV fills the rings of one call even-odd, so
overlapping polygons would cancel out. Coordinates go to pixels in one call per layer, in fixed point (1/8 px).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import shapely

from nuparquet.rendering.draw import TEXT_FONT, rgb_to_bgr

ToPixels = Callable[[np.ndarray], np.ndarray]  # (N, 2) map metres -> (N, 2) pixels
_SHIFT = 3


def polygon_rings(geoms, to_pixels: ToPixels) -> tuple[list[np.ndarray], np.ndarray]:
    """Every ring of the polygons (and multipolygon parts) of `geoms` in fixed-point pixels, and whether each is an
    exterior (each polygon's exterior comes first, then its holes)."""
    polygons = shapely.get_parts(np.asarray(list(geoms), dtype=object)) if len(geoms) else np.empty(0, object)
    polygons = polygons[~shapely.is_empty(polygons)] if len(polygons) else polygons
    if not len(polygons):
        return [], np.zeros(0, bool)
    rings, ring_index = shapely.get_rings(polygons, return_index=True)
    coords, coord_ring = shapely.get_coordinates(rings, return_index=True)
    fixed = np.round(to_pixels(coords) * (1 << _SHIFT)).astype(np.int32)
    split = np.split(fixed, np.flatnonzero(np.diff(coord_ring)) + 1)
    return split, np.r_[True, ring_index[1:] != ring_index[:-1]]


def clip_ring(ring: np.ndarray, x_min: float, y_min: float, x_max: float, y_max: float) -> np.ndarray:
    """(N, 2) polygon ring -> the ring clipped to the rectangle (Sutherland-Hodgman, one edge at a time): what it
    covers inside the rectangle is unchanged, whatever its vertices far outside (a point projected from just in front
    of a camera lies ~1e11 px away, beyond what fixed-point pixels hold)."""
    points = np.asarray(ring, dtype=np.float64).reshape(-1, 2)
    for axis, bound, keep_above in ((0, x_min, True), (0, x_max, False), (1, y_min, True), (1, y_max, False)):
        if not len(points):
            break
        nxt = np.roll(points, -1, axis=0)
        inside = points[:, axis] >= bound if keep_above else points[:, axis] <= bound
        inside_next = np.roll(inside, -1)
        with np.errstate(divide="ignore", invalid="ignore"):  # an edge along the bound is never crossed
            t = (bound - points[:, axis]) / (nxt[:, axis] - points[:, axis])
            crossing = points + t[:, None] * (nxt - points)
        crossing[:, axis] = bound
        out = []
        for k in range(len(points)):  # each vertex kept, then the crossing of its edge where the edge crosses
            if inside[k]:
                out.append(points[k])
            if inside[k] != inside_next[k]:
                out.append(crossing[k])
        points = np.array(out).reshape(-1, 2)
    return points


def fill_polygons(image: np.ndarray, geoms, to_pixels: ToPixels, color, hole_color) -> None:
    """Fill `geoms` in `color`, clearing each one's holes to `hole_color` right after it, in place."""
    rings, exterior = polygon_rings(geoms, to_pixels)
    for ring, is_exterior in zip(rings, exterior):
        cv2.fillPoly(image, [ring], color if is_exterior else hole_color, lineType=cv2.LINE_8, shift=_SHIFT)


def draw_lines(image: np.ndarray, geoms, to_pixels: ToPixels, color, thickness: int) -> None:
    """Draw the line strings of `geoms` (None and empty ones skipped), in place."""
    lines = [g for g in geoms if g is not None and not shapely.is_empty(g)]
    if not lines:
        return
    coords, index = shapely.get_coordinates(np.asarray(lines, dtype=object), return_index=True)
    fixed = np.round(to_pixels(coords) * (1 << _SHIFT)).astype(np.int32)
    cv2.polylines(image, np.split(fixed, np.flatnonzero(np.diff(index)) + 1), False, color, thickness,
                  lineType=cv2.LINE_AA, shift=_SHIFT)


def layer_geometries(map_layers, layer: str, box=None, tokens: Sequence[str] | None = None) -> np.ndarray:
    """The shapes of a layer's records, file order: drivable_area as its polygons one by one (as the devkit draws
    them), the others one per record; only those intersecting `box` (a shapely geometry) and of `tokens` when given."""
    if layer == "drivable_area":
        parts = map_layers.parts[layer]
        geometry, owner = parts.geometry, parts.owner
        tree = parts.tree
    else:
        records = map_layers.layers[layer]
        geometry, owner = records.geometry, np.arange(len(records.geometry))
        tree = records.tree if len(geometry) else None
    if not len(geometry):
        return np.empty(0, object)
    keep = np.sort(tree.query(box, predicate="intersects")) if box is not None else np.arange(len(geometry))
    if tokens is not None:
        wanted = np.isin(map_layers.layers[layer].tokens, list(tokens))
        keep = keep[wanted[owner[keep]]]
    return geometry[keep]


@dataclass
class MapCanvas:
    """A north-up picture of the map rectangle [x_min, x_max] x [y_min, y_max] metres at `px_per_m`; pixel (u, v)
    has its centre at (x_min + (u + 0.5) / s, y_max - (v + 0.5) / s). `image` is BGR."""

    x_min: float
    y_min: float
    x_max: float
    y_max: float
    px_per_m: float
    image: np.ndarray

    @classmethod
    def create(cls, extent, size_px: int = 1000, background_rgb=(255, 255, 255), *,
               height_px: int | None = None) -> MapCanvas:
        """A canvas of `extent` (x_min, y_min, x_max, y_max) whose longer side is `size_px` (or `height_px` high)."""
        x_min, y_min, x_max, y_max = (float(v) for v in extent)
        px_per_m = (height_px / max(y_max - y_min, 1e-6) if height_px
                    else size_px / max(x_max - x_min, y_max - y_min, 1e-6))
        width = max(2, int(round((x_max - x_min) * px_per_m)))
        height = max(2, int(round((y_max - y_min) * px_per_m)))
        image = np.empty((height, width, 3), np.uint8)
        image[:] = rgb_to_bgr(background_rgb)
        return cls(x_min, y_min, x_max, y_max, px_per_m, image)

    @property
    def box(self) -> shapely.Geometry:
        return shapely.box(self.x_min, self.y_min, self.x_max, self.y_max)

    def to_pixels(self, xy) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        s = self.px_per_m
        return np.c_[(xy[:, 0] - self.x_min) * s - 0.5, (self.y_max - xy[:, 1]) * s - 0.5]

    def fill(self, geoms, rgb, alpha: float = 1.0) -> None:
        """Polygons in `rgb` over what is drawn, `alpha` opaque (one blend for the layer: its own overlaps do not
        darken twice)."""
        mask = np.zeros(self.image.shape[:2], np.uint8)
        fill_polygons(mask, geoms, self.to_pixels, 1, 0)
        self._blend(mask.astype(bool), rgb, alpha)

    def lines(self, geoms, rgb, thickness: int = 2, alpha: float = 1.0) -> None:
        mask = np.zeros(self.image.shape[:2], np.uint8)
        draw_lines(mask, geoms, self.to_pixels, 255, thickness)
        self._blend(mask > 0, rgb, alpha * mask[mask > 0].astype(np.float64)[:, None] / 255.0)

    def _blend(self, where: np.ndarray, rgb, alpha) -> None:
        colour = rgb_to_bgr(rgb).astype(np.float64)
        pixels = self.image[where].astype(np.float64)
        self.image[where] = np.rint(pixels * (1.0 - alpha) + colour * alpha).astype(np.uint8)

    def arrows(self, start_xy, end_xy, rgb, thickness: int = 2) -> None:
        colour = tuple(int(c) for c in rgb_to_bgr(rgb))
        for a, b in zip(np.rint(self.to_pixels(start_xy)).astype(int), np.rint(self.to_pixels(end_xy)).astype(int)):
            cv2.arrowedLine(self.image, tuple(a.tolist()), tuple(b.tolist()), colour, thickness, cv2.LINE_AA,
                            tipLength=0.4)

    def dots(self, xy, rgb, radius_px: int = 3) -> None:
        colour = tuple(int(c) for c in rgb_to_bgr(rgb))
        for u, v in np.rint(self.to_pixels(xy)).astype(int).tolist():
            cv2.circle(self.image, (u, v), radius_px, colour, cv2.FILLED, cv2.LINE_AA)

    def rectangle(self, x_min: float, y_min: float, x_max: float, y_max: float, rgb, thickness: int = 2,
                  dash_px: int = 0) -> None:
        """An outline of the rectangle, solid or dashed (dashes of `dash_px`)."""
        corners = self.to_pixels([[x_min, y_min], [x_max, y_min], [x_max, y_max], [x_min, y_max], [x_min, y_min]])
        colour = tuple(int(c) for c in rgb_to_bgr(rgb))
        for a, b in zip(corners[:-1], corners[1:]):
            length = float(np.hypot(*(b - a)))
            pieces = max(1, int(length // (2 * dash_px))) if dash_px else 1
            for k in range(pieces):
                start = a + (b - a) * (2 * k * dash_px / length if dash_px else 0.0)
                end = a + (b - a) * (min(1.0, (2 * k + 1) * dash_px / length) if dash_px else 1.0)
                cv2.line(self.image, tuple(np.rint(start).astype(int).tolist()), tuple(np.rint(end).astype(int).tolist()),
                         colour, thickness, cv2.LINE_AA)

    def text(self, xy, text: str, rgb=(0, 0, 0), font_scale: float = 0.7) -> None:
        u, v = np.rint(self.to_pixels(xy)[0]).astype(int).tolist()
        cv2.putText(self.image, text, (u, v), TEXT_FONT, font_scale, tuple(int(c) for c in rgb_to_bgr(rgb)),
                    max(1, round(font_scale * 2)), cv2.LINE_AA)
