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

Modules: `annotations`, `scenes`, `frames` (ego motion, channel rates), `can_bus`, `map` (map surfaces),
`points` (lidarseg, panoptic, points in boxes), `sections` (what `nuparquet stats` prints). Every query is
listed in `__all__` and loads on first use.
"""

from __future__ import annotations

import importlib

# name -> module of this package: every public query, loaded on first use (polars loads with the first one).
_QUERIES = {
    **dict.fromkeys(("attribute_counts", "class_distribution", "distance_histogram", "points_per_box",
                     "visibility_by_category"), "annotations"),
    **dict.fromkeys(("scene_summary", "track_stats"), "scenes"),
    **dict.fromkeys(("channel_rates", "ego_motion", "ego_speed_summary"), "frames"),
    **dict.fromkeys(("brake_throttle", "can_speed", "speed_over_time", "steering_over_time"), "can_bus"),
    **dict.fromkeys(("annotation_surfaces", "ego_surfaces", "ego_time_on_surfaces", "surfaces_by_category"), "map"),
    **dict.fromkeys(("has_labels", "lidarseg_class_counts", "panoptic_instance_stats", "panoptic_instances",
                     "panoptic_instances_per_frame", "points_in_boxes", "sample_lidarseg_counts", "semantic_label"),
                    "points"),
    **dict.fromkeys(("default_sections", "summary"), "sections"),
}

__all__ = sorted(_QUERIES) + ["EXTRA_SECTIONS", "SECTIONS"]


def __getattr__(name: str):
    if name in _QUERIES:
        value = getattr(importlib.import_module(f"nuparquet.queries.{_QUERIES[name]}"), name)
        globals()[name] = value
        return value
    if name in ("SECTIONS", "EXTRA_SECTIONS"):  # section names: what a plain `stats` prints, and the others
        from nuparquet.queries.sections import SECTIONS as registry

        default = tuple(s.name for s in registry if s.default and not s.requires)
        return default if name == "SECTIONS" else tuple(s.name for s in registry if s.name not in default)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
