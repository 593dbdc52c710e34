"""The devkit's lists of nuScenes scenes with known CAN bus or localisation problems, as public data (scene numbers:
`scene-0161` is 161), and the scene number of a name.

Copied from nuscenes-devkit 1.2.0 so that nothing needs the devkit at run time:
- `CAN_BLACKLIST`: `NuScenesCanBus.can_blacklist`, scenes without CAN bus data (`get_messages` raises for them).
- `ROUTE_BLACKLIST`: `NuScenesCanBus.route_blacklist` at its default 5 m, scenes whose ego poses stray from the
  baseline route (`list_misaligned_routes()` computes the same from the files: `can_bus.routes.misaligned_routes`).
- `NO_VEHICLE_MONITOR`: the scene `get_messages` warns has no vehicle_monitor messages.
- `MAP_MISFIT_BLACKLIST`: `NuScenesMap.render_egoposes_on_fancy_map`'s scenes with a bad fit between ego pose and
  map.
"""

from __future__ import annotations

CAN_BLACKLIST = frozenset([161, 162, 163, 164, 165, 166, 167, 168, 170, 171, 172, 173, 174, 175, 176,
                           309, 310, 311, 312, 313, 314])
ROUTE_BLACKLIST = frozenset([
    71, 73, 74, 75, 76, 85, 100, 101, 106, 107, 108, 109, 110, 112, 113, 114, 115, 116, 117, 118, 119,
    261, 262, 263, 264, 276, 302, 303, 304, 305, 306, 334, 388, 389, 390, 436, 499, 500, 501, 502, 504,
    505, 506, 507, 508, 509, 510, 511, 512, 513, 514, 515, 517, 518, 547, 548, 549, 550, 551, 556, 557,
    558, 559, 560, 561, 562, 563, 564, 565, 730, 731, 733, 734, 735, 736, 737, 738, 778, 780, 781, 782,
    783, 784, 904, 905, 1073, 1074,
])
ROUTE_BLACKLIST_MISALIGNMENT_M = 5.0  # the max_misalignment ROUTE_BLACKLIST was computed at
NO_VEHICLE_MONITOR = frozenset([419])
MAP_MISFIT_BLACKLIST = frozenset([499, 515, 517])


def scene_number(name: str) -> int | None:
    """161 for "scene-0161"; None for a name without a trailing number (other datasets name scenes otherwise)."""
    digits = name.rsplit("-", 1)[-1]
    return int(digits) if digits.isdigit() else None
