"""Scenes whose ego poses stray from the CAN bus baseline route: devkit `NuScenesCanBus.list_misaligned_routes`.

The route is `<scene>_route.json` (`can_bus/route`: x, y points) and the poses the CAN `pose` messages' `pos`
(`can_bus/pose`). A scene is misaligned when some pose lies further than `max_misalignment_m` from every route point
(the directed Hausdorff distance, point to point, as the devkit's `cdist(pose, route)` min-then-max). Only the
converted scenes holding both are looked at (the devkit walks every scene of the can_bus/ folder).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import polars as pl

from nuparquet.columns import to_numpy

if TYPE_CHECKING:
    from nuparquet.dataset import Dataset

_CHUNK = 2048  # poses per distance block: (chunk x route points) floats at a time


def route_misalignment_m(ds: Dataset) -> pl.DataFrame:
    """Per scene with a route and pose messages: ``scene_name, misalignment_m`` (the largest distance from a pose to
    its nearest route point), by scene name."""
    from nuparquet.errors import UsageError

    missing = [name for name in ("can_bus/route", "can_bus/pose") if name not in ds.datasets]
    if missing:
        raise UsageError(f"{ds.root} has no {' or '.join(missing)}: convert a dataroot holding can_bus/")
    routes = ds.scan("can_bus/route").select("scene_name", "point_index", "x", "y").collect().sort("scene_name",
                                                                                                  "point_index")
    poses = ds.scan("can_bus/pose").select("scene_name", "pos").collect()
    route_of = routes.partition_by("scene_name", as_dict=True)
    rows = []
    for (scene,), pose in sorted(poses.partition_by("scene_name", as_dict=True).items()):
        route = route_of.get((scene,))
        if route is None or route.is_empty() or pose.is_empty():
            continue
        route_xy = route.select("x", "y").to_numpy().astype(np.float64)
        pose_xy = to_numpy(pose["pos"], (3,))[:, :2]
        rows.append((scene, float(nearest_route_distance_m(pose_xy, route_xy).max())))
    return pl.DataFrame(rows, schema={"scene_name": pl.String, "misalignment_m": pl.Float64}, orient="row")


def nearest_route_distance_m(pose_xy: np.ndarray, route_xy: np.ndarray) -> np.ndarray:
    """(N,) distance from each of the (N, k) poses to its nearest of the (M, k) route points (M >= 1): the devkit's
    `cdist(pose, route).min(axis=1)`, a block of poses at a time. The squared distances are summed axis by axis, as
    cdist sums them, and the root is taken of each pose's smallest only (the root is monotonic: the same value)."""
    out = []
    for i in range(0, len(pose_xy), _CHUNK):
        block = pose_xy[i:i + _CHUNK]
        squared = np.zeros((len(block), len(route_xy)))
        for axis in range(pose_xy.shape[1]):
            delta = block[:, axis, None] - route_xy[None, :, axis]
            squared += delta * delta
        out.append(np.sqrt(squared.min(axis=1)))
    return np.concatenate(out) if out else np.zeros(0)


def misaligned_routes(ds: Dataset, max_misalignment_m: float = 5.0) -> list[str]:
    """The names of the scenes whose poses stray more than `max_misalignment_m` from the baseline route
    (`list_misaligned_routes`), sorted."""
    misalignment = route_misalignment_m(ds)
    return misalignment.filter(pl.col("misalignment_m") > max_misalignment_m)["scene_name"].to_list()
