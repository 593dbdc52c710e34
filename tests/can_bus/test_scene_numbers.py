"""`can_bus.blacklists.scene_number`: the number the devkit's CAN bus API takes from a scene name
(`int(scene_name[-4:])` in `NuScenesCanBus.get_messages`, checked against its blacklists), for names with more than
one dash too; None for a name without a trailing number (other datasets name scenes otherwise)."""

from __future__ import annotations

import pytest

from nuparquet.can_bus.blacklists import scene_number


@pytest.mark.parametrize("name", ["scene-0161", "scene-0001", "boston-seaport-scene-0161", "night-run-1077"])
def test_the_number_is_the_devkits_last_four_digits(name):
    assert scene_number(name) == int(name[-4:])  # the devkit's rule


@pytest.mark.parametrize("name", ["scene-", "scene-01a1", "log-2018-08-01-scene-x", "scene0161"])
def test_a_name_without_a_number_after_its_last_dash_has_none(name):
    assert scene_number(name) is None
