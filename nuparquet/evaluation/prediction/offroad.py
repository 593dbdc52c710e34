"""The devkit's `OffRoadRate`: a mode is off road when any of the points of its path (a cubic smoothing spline
through its distinct points, sampled at 200 points; the points themselves when there are 3 or fewer) falls outside
the map canvas or on a pixel of no drivable area, at 10 pixels per metre of the whole map's `get_map_mask`.

The mask is `map.mask`'s over the devkit's own canvas of the map (its `get_map_mask` hard-codes the four nuScenes
maps' sizes) pixel for pixel, painted once per map evaluated and dropped after its look-ups (the devkit keeps
all four); the spline is scipy's `splprep`/`splev`, called with the devkit's arguments (the
numbers are FITPACK's, as in the devkit); the pixel look-ups are done for every point of every mode at once."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nuparquet.errors import InputError

PIXELS_PER_METRE = 10
NUMBER_OF_POINTS = 200
# the devkit's NuScenesMapExplorer.get_map_mask: map_dims (x, y metres) per map
DEVKIT_MAP_DIMS_M = {"singapore-onenorth": (1585.6, 2025.0), "singapore-hollandvillage": (2808.3, 2922.9),
                     "singapore-queenstown": (3228.6, 3687.1), "boston-seaport": (2979.5, 2118.1)}


@dataclass
class DrivableArea:
    """The devkit's `get_map_mask(None, 0, ['drivable_area'], None)[0]` of a map, as the pixel rings it paints
    (`map.mask.polygon_rings`) and its (H, W) canvas: painted when looked up (`at`), not kept."""

    rings: list
    canvas_size: tuple[int, int]

    def at(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """(N,) uint8 the mask's pixels at (rows, cols), all inside the canvas (the whole canvas painted: its
        pixels are OpenCV's on that image only, `map.mask.paint_polygons`)."""
        from nuparquet.map.mask import paint_polygons

        mask = np.zeros(self.canvas_size, np.uint8)
        paint_polygons(mask, self.rings)
        return mask[rows, cols]


def drivable_area(dataset, location: str) -> DrivableArea:
    """The drivable-area mask of `location`'s map on the devkit's canvas of it (10 pixels per metre)."""
    from nuparquet.map.mask import polygon_rings

    if location not in DEVKIT_MAP_DIMS_M:
        raise InputError(f"location {location!r} is not one of the devkit's maps ({', '.join(DEVKIT_MAP_DIMS_M)}): "
                         "its OffRoadRate has no canvas for it")
    width_m, height_m = DEVKIT_MAP_DIMS_M[location]
    patch_box = (width_m / 2, height_m / 2, height_m, width_m)
    canvas_size = tuple(int(v) for v in np.round(np.array((patch_box[2], patch_box[3])) * 10).astype(np.int32))
    rings = polygon_rings(dataset.map(location), "drivable_area", patch_box, 0, canvas_size)
    return DrivableArea(rings, canvas_size)


def interpolate_path(mode: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The devkit's `OffRoadRate.interpolate_path`: x, y of the path through the mode's distinct points (first
    occurrences, in order; compared as the devkit's tuples compare, -0.0 equal to 0.0)."""
    from scipy import interpolate

    seen, ordered = set(), []
    for row in mode:
        row_tuple = tuple(row)
        if row_tuple not in seen:
            seen.add(row_tuple)
            ordered.append(row_tuple)
    unique_points = np.atleast_2d(np.array(ordered))
    if unique_points.shape[0] <= 3:
        return unique_points[:, 0], unique_points[:, 1]
    knots, _ = interpolate.splprep([unique_points[:, 0], unique_points[:, 1]], k=3, s=0.1)
    x, y = interpolate.splev(np.linspace(0, 1, NUMBER_OF_POINTS), knots)
    return x, y


def off_road_modes(predictions: list[np.ndarray], masks: list[DrivableArea]) -> list[np.ndarray]:
    """Per agent, (M,) bool: whether each mode of its (M, T, 2) prediction leaves the drivable area of its map
    (the mask objects are shared by the agents of one map)."""
    by_mask: dict[int, list[int]] = {}
    for i, mask in enumerate(masks):
        by_mask.setdefault(id(mask), []).append(i)
    out: list[np.ndarray] = [np.zeros(0, bool)] * len(predictions)
    for members in by_mask.values():
        mask = masks[members[0]]
        xs, ys, counts = [], [], []
        for i in members:
            for mode in predictions[i]:
                x, y = interpolate_path(mode)
                xs.append(x)
                ys.append(y)
                counts.append(len(x))
        x, y = np.concatenate(xs), np.concatenate(ys)
        # x -> column, y -> row (the mask is already flipped); truncation towards zero, as the devkit's astype
        row = (y * PIXELS_PER_METRE).astype("int")
        col = (x * PIXELS_PER_METRE).astype("int")
        max_row, max_col = mask.canvas_size
        outside = (row < 0) | (row >= max_row) | (col < 0) | (col >= max_col)
        on_road = np.zeros(len(row), bool)
        on_road[~outside] = mask.at(row[~outside], col[~outside]) != 0
        starts = np.r_[0, np.cumsum(counts)[:-1]]
        violation = np.logical_or.reduceat(~on_road, starts)
        modes = np.cumsum([0] + [len(predictions[i]) for i in members])
        for j, i in enumerate(members):
            out[i] = violation[modes[j]:modes[j + 1]]
    return out
