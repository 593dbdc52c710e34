"""The sections `nuparquet stats` prints, registered in one place.

A section is a named canned query with a title. Adding one (a CAN bus summary, map layers per annotation,
lidarseg class counts) is one `Section(...)` entry in `SECTIONS` below; `requires` names the datasets it reads,
so a section whose inputs were not converted (no `can_bus/` folder, no `--sensors lidar`) is left out of the
default run instead of failing.

    Section("can_speed", "CAN speed vs ego pose speed per scene", _query("can_bus:can_speed"),
            requires=("sample_can_bus",))
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import polars as pl

    from nuparquet.dataset import Dataset
    from nuparquet.queries.inputs import Scene


@dataclass(frozen=True)
class SectionOptions:
    """Parameters some sections take (the `stats` flags)."""

    bin_width_m: float = 10.0


def _query(path: str, **fixed: Any) -> Callable[[Dataset, Scene, SectionOptions], pl.LazyFrame]:
    """The query `module:function` of `nuparquet.queries`, imported when the section runs (the registry itself
    stays light: `nuparquet stats --help` lists the sections without loading polars)."""
    module, function = path.split(":")

    def run(ds: Dataset, scene: Scene, options: SectionOptions) -> pl.LazyFrame:
        query = getattr(importlib.import_module(f"nuparquet.queries.{module}"), function)
        extra = {"bin_width_m": options.bin_width_m} if function == "distance_histogram" else {}
        return query(ds, scene=scene, **fixed, **extra)

    return run


def _has_labels(kind: str) -> Callable[[Dataset], bool]:
    def check(ds: Dataset) -> bool:
        from nuparquet.queries.points import has_labels

        return has_labels(ds, kind)

    return check


@dataclass(frozen=True)
class Section:
    name: str
    title: str
    query: Callable[[Dataset, Scene, SectionOptions], pl.LazyFrame]
    default: bool = True  # printed by a plain `nuparquet stats`; else only on request (--only)
    requires: tuple[str, ...] = ()  # datasets the query reads beyond the core four; absent -> not in the default run
    when: Callable[[Dataset], bool] | None = None  # and in the default run only if this holds (labels converted)
    unmet: str = ""  # what is missing when `when` does not hold (asking for the section then is a usage error)


SECTIONS: tuple[Section, ...] = (
    Section("scenes", "Scenes (like NuScenes.list_scenes; anns_list_scenes leaves out the last sample as it does)",
            _query("scenes:scene_summary")),
    Section("class_distribution", "Categories (like NuScenes.list_categories: mean±std, ddof=0)",
            _query("annotations:class_distribution")),
    Section("attributes", "Attributes (like NuScenes.list_attributes)", _query("annotations:attribute_counts")),
    Section("visibility", "Visibility level by category (annotation counts)",
            _query("annotations:visibility_by_category")),
    Section("points_per_box", "Points per box by category (percentiles; zero = share of boxes with no point)",
            _query("annotations:points_per_box")),
    Section("distance_histogram", "Distance to the ego vehicle by category (annotation counts per bin, metres)",
            _query("annotations:distance_histogram")),
    Section("tracks", "Tracks (instances) by category", _query("scenes:track_stats")),
    Section("ego_speed", "Ego motion per scene (reference lidar keyframe poses)", _query("frames:ego_speed_summary")),
    Section("channel_rates", "Frames per channel (rates measured from timestamps)", _query("frames:channel_rates")),
    Section("can_speed", "CAN bus speed per scene, m/s (vehicle_monitor vehicle_speed, pose |vel|) vs ego-pose speed",
            _query("can_bus:can_speed"), requires=("can_bus/vehicle_monitor", "can_bus/pose")),
    Section("brake_throttle", "CAN bus pedals per scene (vehicle_monitor: share of messages pressed, mean, max)",
            _query("can_bus:brake_throttle"), requires=("can_bus/vehicle_monitor",)),
    Section("map_surfaces", "Where the boxes are on the map, by category (annotation counts per surface)",
            _query("map:surfaces_by_category"), requires=("map/lane", "map/road_segment")),
    Section("ego_on_map", "Ego keyframes per scene on each map surface (shares; intersection = ego time there)",
            _query("map:ego_time_on_surfaces"), requires=("map/lane", "map/road_segment")),
    Section("lidarseg", "nuScenes-lidarseg: labelled lidar points per class (like NuScenes.list_lidarseg_categories)",
            _query("points:lidarseg_class_counts"), requires=("lidar_points",), when=_has_labels("lidarseg"),
            unmet="lidar_points/ holds no lidarseg labels (the dataroot had no lidarseg/ label files when it was "
                  "converted)"),
    Section("panoptic", "Panoptic nuScenes: instances per class (like NuScenes.list_panoptic_instances, ddof=0)",
            _query("points:panoptic_instance_stats"), requires=("lidar_points",), when=_has_labels("panoptic"),
            unmet="lidar_points/ holds no panoptic labels (the dataroot had no panoptic/ label files when it was "
                  "converted)"),
    Section("class_distribution_by_scene", "Categories per scene",
            _query("annotations:class_distribution", by_scene=True), default=False),
    Section("channel_rates_by_scene", "Frames per channel and scene", _query("frames:channel_rates", by_scene=True),
            default=False),
    Section("ego_motion", "Ego motion over time (reference lidar keyframe poses)", _query("frames:ego_motion"),
            default=False),
    Section("can_speed_over_time", "Speed over time: CAN vehicle_monitor, CAN pose and ego pose (m/s)",
            _query("can_bus:speed_over_time"), default=False, requires=("can_bus/vehicle_monitor", "can_bus/pose")),
    Section("steering_over_time", "Steering wheel angle (rad) and yaw rate (rad/s) over time, CAN bus",
            _query("can_bus:steering_over_time"), default=False,
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
    unmet = [s for s in names if BY_NAME[s].when is not None and not BY_NAME[s].when(ds)]
    if unmet:  # asked for by name (--only) while its data is absent: say so rather than print zeros
        from nuparquet.errors import UsageError

        raise UsageError("; ".join(f"section {s}: {BY_NAME[s].unmet}" for s in unmet))
    options = SectionOptions(bin_width_m=bin_width_m)
    return {name: BY_NAME[name].query(ds, scene, options) for name in names}
