"""Every dataset `nuparquet convert` builds beside `tables/`, registered in one place: `BUILDERS`, in the order
the conversion runs them. A new dataset is one module under `builders/` exporting `BUILDER` (see
`nuparquet.conversion.builder`) and one entry here."""

from __future__ import annotations

from nuparquet.conversion.builder import Builder
from nuparquet.conversion.builders import (
    annotations, can_bus, frames, instances, map_expansion, points, sample_can_bus, scenes, sensor_files,
)

BUILDERS: tuple[Builder, ...] = (
    frames.BUILDER, annotations.BUILDER, scenes.BUILDER, instances.BUILDER, can_bus.BUILDER, sample_can_bus.BUILDER,
    map_expansion.BUILDER, points.LIDAR_BUILDER, points.RADAR_BUILDER,
    sensor_files.CAMERA_BUILDER, sensor_files.LIDAR_BUILDER, sensor_files.RADAR_BUILDER,
)
