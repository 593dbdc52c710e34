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

from nuparquet.queries.annotations import (
    attribute_counts, class_distribution, distance_histogram, points_per_box, visibility_by_category,
)
from nuparquet.queries.frames import channel_rates, ego_motion, ego_speed_summary
from nuparquet.queries.scenes import scene_summary, track_stats

__all__ = ["attribute_counts", "channel_rates", "class_distribution", "distance_histogram", "ego_motion",
           "ego_speed_summary", "points_per_box", "scene_summary", "summary", "track_stats",
           "visibility_by_category", "SECTIONS", "EXTRA_SECTIONS"]

# --- everything `nuparquet stats` prints: the section registry (queries/sections.py) ------------------------------

from nuparquet.queries.sections import SECTIONS as _REGISTRY, summary  # noqa: E402 (after the queries it registers)

SECTIONS = tuple(s.name for s in _REGISTRY if s.default and not s.requires)
EXTRA_SECTIONS = tuple(s.name for s in _REGISTRY if s.name not in SECTIONS)
