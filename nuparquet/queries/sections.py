"""The sections `nuparquet stats` prints, registered in one place.

A section is a named canned query with a title. Adding one (a CAN bus summary, map layers per annotation,
lidarseg class counts) is one `Section(...)` entry in `SECTIONS` below; `requires` names the datasets it reads,
so a section whose inputs were not converted (no `can_bus/` folder, no `--sensors lidar`) is left out of the
default run instead of failing.

    Section("can_speed", "CAN speed vs ego pose speed per scene", lambda ds, scene, o: can_speed(ds, scene=scene),
            requires=("sample_can_bus",))
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import polars as pl

from nuparquet.queries.annotations import (
    attribute_counts, class_distribution, distance_histogram, points_per_box, visibility_by_category,
)
from nuparquet.queries.can_bus import brake_throttle, can_speed, speed_over_time, steering_over_time
from nuparquet.queries.frames import channel_rates, ego_motion, ego_speed_summary
from nuparquet.queries.map import ego_time_on_surfaces, surfaces_by_category
from nuparquet.queries.points import has_labels, lidarseg_class_counts, panoptic_instance_stats
from nuparquet.queries.scenes import scene_summary, track_stats

if TYPE_CHECKING:
    from nuparquet.dataset import Dataset
    from nuparquet.queries.inputs import Scene


@dataclass(frozen=True)
class SectionOptions:
    """Parameters some sections take (the `stats` flags)."""

    bin_width_m: float = 10.0


@dataclass(frozen=True)
class Section:
    name: str
    title: str
    query: Callable[[Dataset, Scene, SectionOptions], pl.LazyFrame]
    default: bool = True  # printed by a plain `nuparquet stats`; else only on request (--only)
    requires: tuple[str, ...] = ()  # datasets the query reads beyond the core four; absent -> not in the default run
    when: Callable[[Dataset], bool] | None = None  # and in the default run only if this holds (labels converted)


SECTIONS: tuple[Section, ...] = (
    Section("scenes", "Scenes (like NuScenes.list_scenes; anns_list_scenes leaves out the last sample as it does)",
            lambda ds, scene, o: scene_summary(ds, scene=scene)),
    Section("class_distribution", "Categories (like NuScenes.list_categories: mean±std, ddof=0)",
            lambda ds, scene, o: class_distribution(ds, scene=scene)),
    Section("attributes", "Attributes (like NuScenes.list_attributes)",
            lambda ds, scene, o: attribute_counts(ds, scene=scene)),
    Section("visibility", "Visibility level by category (annotation counts)",
            lambda ds, scene, o: visibility_by_category(ds, scene=scene)),
    Section("points_per_box", "Points per box by category (percentiles; zero = share of boxes with no point)",
            lambda ds, scene, o: points_per_box(ds, scene=scene)),
    Section("distance_histogram", "Distance to the ego vehicle by category (annotation counts per bin, metres)",
            lambda ds, scene, o: distance_histogram(ds, bin_width_m=o.bin_width_m, scene=scene)),
    Section("tracks", "Tracks (instances) by category", lambda ds, scene, o: track_stats(ds, scene=scene)),
    Section("ego_speed", "Ego motion per scene (reference lidar keyframe poses)",
            lambda ds, scene, o: ego_speed_summary(ds, scene=scene)),
    Section("channel_rates", "Frames per channel (rates measured from timestamps)",
            lambda ds, scene, o: channel_rates(ds, scene=scene)),
    Section("can_speed", "CAN bus speed per scene, m/s (vehicle_monitor wheel speed, pose |vel|) vs ego-pose speed",
            lambda ds, scene, o: can_speed(ds, scene=scene), requires=("can_bus/vehicle_monitor", "can_bus/pose")),
    Section("brake_throttle", "CAN bus pedals per scene (vehicle_monitor: share of messages pressed, mean, max)",
            lambda ds, scene, o: brake_throttle(ds, scene=scene), requires=("can_bus/vehicle_monitor",)),
    Section("map_surfaces", "Where the boxes are on the map, by category (annotation counts per surface)",
            lambda ds, scene, o: surfaces_by_category(ds, scene=scene), requires=("map/lane", "map/road_segment")),
    Section("ego_on_map", "Ego keyframes per scene on each map surface (shares; intersection = ego time there)",
            lambda ds, scene, o: ego_time_on_surfaces(ds, scene=scene), requires=("map/lane", "map/road_segment")),
    Section("lidarseg", "nuScenes-lidarseg: labelled lidar points per class (like NuScenes.list_lidarseg_categories)",
            lambda ds, scene, o: lidarseg_class_counts(ds, scene=scene), requires=("lidar_points",),
            when=lambda ds: has_labels(ds, "lidarseg")),
    Section("panoptic", "Panoptic nuScenes: instances per class (like NuScenes.list_panoptic_instances, ddof=0)",
            lambda ds, scene, o: panoptic_instance_stats(ds, scene=scene), requires=("lidar_points",),
            when=lambda ds: has_labels(ds, "panoptic")),
    Section("class_distribution_by_scene", "Categories per scene",
            lambda ds, scene, o: class_distribution(ds, by_scene=True, scene=scene), default=False),
    Section("channel_rates_by_scene", "Frames per channel and scene",
            lambda ds, scene, o: channel_rates(ds, by_scene=True, scene=scene), default=False),
    Section("ego_motion", "Ego motion over time (reference lidar keyframe poses)",
            lambda ds, scene, o: ego_motion(ds, scene=scene), default=False),
    Section("can_speed_over_time", "Speed over time: CAN vehicle_monitor, CAN pose and ego pose (m/s)",
            lambda ds, scene, o: speed_over_time(ds, scene=scene), default=False,
            requires=("can_bus/vehicle_monitor", "can_bus/pose")),
    Section("steering_over_time", "Steering wheel angle (rad) and yaw rate (rad/s) over time, CAN bus",
            lambda ds, scene, o: steering_over_time(ds, scene=scene), default=False,
            requires=("can_bus/steeranglefeedback", "can_bus/pose")),
)
BY_NAME = {s.name: s for s in SECTIONS}


def default_sections(ds: Dataset | None = None) -> tuple[str, ...]:
    """The sections a plain `nuparquet stats` prints: every default one whose datasets `ds` holds."""
    held = None if ds is None else set(ds.datasets)
    return tuple(s.name for s in SECTIONS if s.default and (held is None or (
        held.issuperset(s.requires) and (s.when is None or s.when(ds)))))


def summary(ds: Dataset, *, scene: Scene = None, sections: Sequence[str] | None = None,
            bin_width_m: float = 10.0) -> dict[str, pl.LazyFrame]:
    """The canned results `nuparquet stats` prints, by section name (default: `default_sections(ds)`)."""
    names = default_sections(ds) if sections is None else tuple(sections)
    unknown = [s for s in names if s not in BY_NAME]
    if unknown:
        raise ValueError(f"unknown section(s) {', '.join(unknown)}; valid: {', '.join(BY_NAME)}")
    missing = {s: [d for d in BY_NAME[s].requires if d not in ds.datasets] for s in names}
    missing = {s: d for s, d in missing.items() if d}
    if missing:
        from nuparquet.errors import UsageError

        raise UsageError("; ".join(f"section {s} needs dataset(s) {', '.join(d)}, not in this output"
                                   for s, d in missing.items()))
    options = SectionOptions(bin_width_m=bin_width_m)
    return {name: BY_NAME[name].query(ds, scene, options) for name in names}
