"""`get_map_mask` pixel for pixel: the same clip, rotation, translation and scaling arithmetic as the devkit
(shapely's affine formulas applied to all coordinates at once), then the same OpenCV calls per clipped geometry in
file order (a geometry's holes cleared right after it, so overlaps paint as the devkit's do). Deviation: where a
line layer's clip is a MultiLineString the devkit (shapely 2) raises TypeError iterating it; here each part is
drawn. traffic_light yields no mask, as in the devkit (so the stack has one channel fewer)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import cv2
import numpy as np
import shapely

from nuparquet.map.layers import LINE_LAYERS, NON_GEOMETRIC_LAYERS, POLYGON_LAYERS

if TYPE_CHECKING:
    from nuparquet.map.queries import MapLayers


def map_mask(layers: MapLayers, patch_box: tuple[float, float, float, float], patch_angle_deg: float,
             layer_names: tuple[str, ...] | list[str] | None = None,
             canvas_size: tuple[int, int] = (100, 100)) -> np.ndarray:
    """(C, H, W) uint8 masks of the patch [x_center, y_center, height, width] rotated by `patch_angle_deg`."""
    layer_names = list(layer_names or NON_GEOMETRIC_LAYERS)
    if canvas_size is None:
        canvas_size = tuple(np.round(np.array((patch_box[2], patch_box[3])) * 10).astype(np.int32))
    px, py, ph, pw = patch_box
    patch = _patch(patch_box, patch_angle_deg)
    local = _patch((0.0, 0.0, ph, pw), 0.0)
    h, w = canvas_size
    scale_x, scale_y = w / pw, h / ph
    trans_x, trans_y = -0.0 + pw / 2.0, -0.0 + ph / 2.0
    masks = []
    for layer in layer_names:
        if layer == "traffic_light":
            continue
        mask = np.zeros(canvas_size, np.uint8)
        if layer in POLYGON_LAYERS:
            paint_polygons(mask, polygon_rings(layers, layer, patch_box, patch_angle_deg, canvas_size))
        elif layer in LINE_LAYERS:
            records = layers.layers[layer]
            geoms = records.geometry
            ok = ~shapely.is_missing(geoms)
            ok[ok] = ~shapely.is_empty(geoms[ok])
            candidates = np.sort(records.tree.query(patch, predicate="intersects"))
            candidates = candidates[ok[candidates]]
            clipped = _to_local(shapely.intersection(geoms[candidates], patch), patch_angle_deg, px, py)
            clipped = shapely.intersection(clipped[~shapely.is_empty(clipped)], local)
            clipped = clipped[~shapely.is_empty(clipped)]
            clipped = _affine(_affine(clipped, 1.0, 0.0, 0.0, 1.0, trans_x, trans_y),
                              scale_x, 0.0, 0.0, scale_y, 0.0 - 0.0 * scale_x, 0.0 - 0.0 * scale_y)
            for geom in clipped:
                for part in shapely.get_parts(geom):
                    cv2.polylines(mask, [np.asarray(part.coords, np.int32).reshape(-1, 2)], False, 1, 2)
        else:
            raise ValueError(f"{layer} is not a valid layer")
        masks.append(mask)
    return np.array(masks)


def polygon_rings(layers: MapLayers, layer: str, patch_box: tuple[float, float, float, float],
                  patch_angle_deg: float, canvas_size: tuple[int, int]) -> list[tuple[list, list]]:
    """Per clipped geometry of a polygon layer, in the devkit's paint order: its (exterior rings, hole rings) as
    (K, 2) int32 pixel x, y of the canvas, as `map_mask` paints them."""
    px, py, ph, pw = patch_box
    patch = _patch(patch_box, patch_angle_deg)
    local = _patch((0.0, 0.0, ph, pw), 0.0)
    h, w = canvas_size
    scale_x, scale_y = w / pw, h / ph
    trans_x, trans_y = -0.0 + pw / 2.0, -0.0 + ph / 2.0
    parts = layers.parts[layer]
    geoms = parts.geometry
    candidates = np.sort(parts.tree.query(patch, predicate="intersects"))
    if layer != "drivable_area":  # the devkit skips invalid polygons of the other layers
        candidates = candidates[shapely.is_valid(geoms[candidates])]
    clipped = _to_local(shapely.intersection(geoms[candidates], patch), patch_angle_deg, px, py)
    clipped = shapely.intersection(clipped[~shapely.is_empty(clipped)], local)
    clipped = clipped[~shapely.is_empty(clipped)]
    clipped = _affine(_affine(clipped, 1.0, 0.0, 0.0, 1.0, trans_x, trans_y),
                      scale_x, 0.0, 0.0, scale_y, 0.0 - 0.0 * scale_x, 0.0 - 0.0 * scale_y)
    rings = []
    for geom in clipped:
        polygons = shapely.get_parts(geom)
        rings.append(([np.asarray(p.exterior.coords).round().astype(np.int32) for p in polygons],
                      [np.asarray(r.coords).round().astype(np.int32) for p in polygons for r in p.interiors]))
    return rings


def paint_polygons(mask: np.ndarray, rings: list[tuple[list, list]]) -> None:
    """Paint `polygon_rings` into the canvas `mask` per geometry (its holes cleared before the next, so overlaps
    paint as the devkit's do). Only on the whole canvas: OpenCV draws each ring's outline with its line clipped to
    the image, so a tile of the canvas (an offset, a smaller image) paints some edge pixels differently."""
    for exteriors, interiors in rings:
        cv2.fillPoly(mask, exteriors, 1)
        cv2.fillPoly(mask, interiors, 0)


def _patch(patch_box, patch_angle_deg: float):
    """The devkit's get_patch_coord."""
    from shapely import affinity

    px, py, ph, pw = patch_box
    patch = shapely.box(px - pw / 2.0, py - ph / 2.0, px + pw / 2.0, py + ph / 2.0)
    return affinity.rotate(patch, patch_angle_deg, origin=(px, py), use_radians=False)


def _affine(geoms: np.ndarray, a: float, b: float, d: float, e: float, xoff: float, yoff: float) -> np.ndarray:
    """shapely.affinity.affine_transform's 2D arithmetic, applied to every coordinate of every geometry at once."""
    if not len(geoms):
        return geoms

    def transform(coords: np.ndarray) -> np.ndarray:
        x, y = coords.T
        return np.stack([a * x + b * y + xoff, d * x + e * y + yoff]).T

    return shapely.transform(geoms, transform)


def _to_local(geoms: np.ndarray, patch_angle_deg: float, px: float, py: float) -> np.ndarray:
    """Rotate by -angle about the patch centre (shapely.affinity.rotate's matrix), then move the centre to 0."""
    angle = -patch_angle_deg * math.pi / 180.0
    cosp, sinp = math.cos(angle), math.sin(angle)
    cosp = 0.0 if abs(cosp) < 2.5e-16 else cosp
    sinp = 0.0 if abs(sinp) < 2.5e-16 else sinp
    rotated = _affine(geoms, cosp, -sinp, sinp, cosp, px - px * cosp + py * sinp, py - px * sinp - py * cosp)
    return _affine(rotated, 1.0, 0.0, 0.0, 1.0, -px, -py)
