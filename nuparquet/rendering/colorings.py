"""What points can be coloured by: the one vocabulary of every picture, video and flag (light: the option classes
and the CLI's parser read it). The devkit's `render_intensity`, `show_lidarseg` and `show_panoptic` are translated
to it in `devkit/renders.py`; `point_colors` holds the colours themselves."""

from __future__ import annotations

from typing import Literal, get_args

from nuparquet.errors import UsageError

# "depth": the devkit's default (camera depth on an image, distance from the sensor seen from above, height in the
# bird's-eye view); "height" (seen from above); lidar "intensity"; the "lidarseg" class; the "panoptic" label
PointColor = Literal["depth", "height", "intensity", "lidarseg", "panoptic"]
POINT_COLORS: tuple[str, ...] = get_args(PointColor)
LABEL_COLORS = ("lidarseg", "panoptic")
# `--lidar-color`, the flag of videos and pictures
LidarColor = Literal["depth", "intensity", "lidarseg", "panoptic"]
LIDAR_COLORS: tuple[str, ...] = get_args(LidarColor)


def label_mode(point_color: str) -> str | None:
    """"lidarseg" / "panoptic" when `point_color` colours by labels, else None; UsageError for an unknown colour."""
    if point_color not in POINT_COLORS:
        raise UsageError(f"point colour must be one of {', '.join(POINT_COLORS)}, got {point_color!r}")
    return point_color if point_color in LABEL_COLORS else None
