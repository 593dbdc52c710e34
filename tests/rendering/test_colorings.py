"""The one point-colour vocabulary (`rendering.colorings`) and the devkit's three colouring flags translated to it
(`devkit/renders.py`), with the devkit's precedence: lidarseg over panoptic (`'lidarseg' if show_lidarseg else
'panoptic'`), intensity beside labels refused (the devkit asserts)."""

from __future__ import annotations

import pytest

from nuparquet.devkit.renders import _point_color
from nuparquet.errors import UsageError
from nuparquet.rendering import colorings


def test_only_label_colours_have_a_label_mode_and_unknown_colours_are_refused():
    assert [colorings.label_mode(c) for c in colorings.POINT_COLORS] == [None, None, None, "lidarseg", "panoptic"]
    assert set(colorings.LIDAR_COLORS) == set(colorings.POINT_COLORS) - {"height"}
    with pytest.raises(UsageError, match="point colour must be one of depth, height, intensity, lidarseg, panoptic"):
        colorings.label_mode("distance")


@pytest.mark.parametrize(("flags", "expected"), [
    ((False, False, False), "depth"), ((True, False, False), "intensity"), ((False, True, False), "lidarseg"),
    ((False, False, True), "panoptic"), ((False, True, True), "lidarseg"),
])
def test_the_devkit_flags_become_one_point_colour(flags, expected):
    assert _point_color(*flags) == expected


@pytest.mark.parametrize("flags", [(True, True, False), (True, False, True)])
def test_intensity_beside_labels_is_refused(flags):
    with pytest.raises(UsageError, match="intensity or by labels, not both"):
        _point_color(*flags)
