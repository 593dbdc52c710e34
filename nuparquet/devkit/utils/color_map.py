"""The devkit's `nuscenes.utils.color_map`: the RGB colour of every nuScenes (and nuScenes-lidarseg) class."""

from __future__ import annotations

from nuparquet.rendering.palette import CATEGORY_RGB


def get_colormap() -> dict[str, tuple[int, int, int]]:
    """{class name: (r, g, b)}, a new dict in the devkit's order on every call (callers may change it)."""
    return dict(CATEGORY_RGB)
