"""Canned analytics over a converted dataset: plain functions from LazyFrames to a LazyFrame.

Every query takes either a `nuparquet.dataset.Dataset` (it scans what it needs) or the LazyFrame(s) of the
dataset(s) it names, and returns a `polars.LazyFrame`: nothing is read until you `.collect()`. With
``scene="scene-0061"`` (or a list of names) the scene filter is applied first, so polars reads only the row
groups whose ``scene_name`` statistics can hold that scene (the datasets are sorted by scene).

    ds = nuparquet.open("OUT")
    class_distribution(ds).collect()                       # like NuScenes.list_categories()
    class_distribution(ds.scan("annotations"), by_scene=True, scene="scene-0061").collect()

Category and channel columns come out as plain strings, rows sorted by their keys. Standard deviations are
population deviations (ddof=0, as ``numpy.std``); quantiles interpolate linearly (as ``numpy.percentile``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import polars as pl

from nuparquet.queries.annotations import (
    attribute_counts, class_distribution, distance_histogram, points_per_box, visibility_by_category,
)
from nuparquet.queries.frames import channel_rates, ego_motion, ego_speed_summary
from nuparquet.queries.scenes import scene_summary, track_stats

if TYPE_CHECKING:
    from nuparquet.dataset import Dataset
    from nuparquet.queries.inputs import Scene

__all__ = ["attribute_counts", "channel_rates", "class_distribution", "distance_histogram", "ego_motion",
           "ego_speed_summary", "points_per_box", "scene_summary", "summary", "track_stats",
           "visibility_by_category", "SECTIONS", "EXTRA_SECTIONS"]

# --- everything `nuparquet stats` prints -----------------------------------------------------------------------

SECTIONS = ("scenes", "class_distribution", "attributes", "visibility", "points_per_box", "distance_histogram",
            "tracks", "ego_speed", "channel_rates")
EXTRA_SECTIONS = ("class_distribution_by_scene", "channel_rates_by_scene", "ego_motion")


def summary(ds: Dataset, *, scene: Scene = None, sections: Sequence[str] = SECTIONS,
            bin_width_m: float = 10.0) -> dict[str, pl.LazyFrame]:
    """The canned results `nuparquet stats` prints, by section name (`SECTIONS`; `EXTRA_SECTIONS` on request)."""
    builders = {
        "scenes": lambda: scene_summary(ds, scene=scene),
        "class_distribution": lambda: class_distribution(ds, scene=scene),
        "class_distribution_by_scene": lambda: class_distribution(ds, by_scene=True, scene=scene),
        "attributes": lambda: attribute_counts(ds, scene=scene),
        "visibility": lambda: visibility_by_category(ds, scene=scene),
        "points_per_box": lambda: points_per_box(ds, scene=scene),
        "distance_histogram": lambda: distance_histogram(ds, bin_width_m=bin_width_m, scene=scene),
        "tracks": lambda: track_stats(ds, scene=scene),
        "ego_speed": lambda: ego_speed_summary(ds, scene=scene),
        "ego_motion": lambda: ego_motion(ds, scene=scene),
        "channel_rates": lambda: channel_rates(ds, scene=scene),
        "channel_rates_by_scene": lambda: channel_rates(ds, by_scene=True, scene=scene),
    }
    unknown = [s for s in sections if s not in builders]
    if unknown:
        raise ValueError(f"unknown section(s) {', '.join(unknown)}; valid: {', '.join(builders)}")
    return {name: builders[name]() for name in sections}
