"""The plane seen from above (`rendering.topview.PlaneView`) on inputs whose answer is known without our code: the
devkit's `Box.render` heading line for a tilted box, and a map patch placed by hand under a yawed ego frame."""

from __future__ import annotations

import os

import numpy as np
import pytest
import shapely

from nuparquet.rendering.bev import BACKGROUND_BGR, MAP_STYLE
from nuparquet.rendering.pictures.topview import PlaneView

os.environ.setdefault("MPLBACKEND", "Agg")
BACKGROUND = np.array(BACKGROUND_BGR)


def _drawn(picture, u: int, v: int) -> bool:
    return bool(np.abs(picture[v, u].astype(int) - BACKGROUND).max() > 60)


@pytest.mark.parametrize("pitch_deg", [30.0, -30.0])
def test_the_heading_line_runs_from_the_bottom_centre_to_the_bottom_front_as_box_render_draws_it(pitch_deg):
    """A 4 m box facing +x, pitched about y so that its top and bottom front edges lie 1 m apart seen from above
    (h sin 30°): the heading line must end at the bottom front edge (the devkit's `Box.render`: corners 2, 3),
    not at the top front one. Along the box's middle line (y = const), a point is drawn iff it lies on the devkit's
    heading segment, away from the edges that cross that line."""
    import matplotlib.pyplot as plt
    from nuscenes.utils.data_classes import Box
    from pyquaternion import Quaternion

    y_mid = 0.01  # the box's middle line falls on pixel row 199 exactly: (4 - 0.01) * 50 - 0.5
    box = Box([0.0, y_mid, 0.0], [2.0, 4.0, 2.0], Quaternion(axis=[0, 1, 0], degrees=pitch_deg))
    corners = box.corners().T  # (8, 3), the devkit's order
    figure, axis = plt.subplots()
    box.render(axis, view=np.eye(3), normalize=False)
    heading = np.c_[axis.lines[-1].get_xdata(), axis.lines[-1].get_ydata()]  # the devkit's last line: the heading
    plt.close(figure)
    assert np.allclose(heading[:, 1], y_mid)
    # the top and bottom front edges are 1 m apart seen from above: the test tells them apart
    top_front, bottom_front = corners[[0, 1], 0].mean(), corners[[2, 3], 0].mean()
    assert abs(top_front - bottom_front) == pytest.approx(1.0) and heading[1, 0] == pytest.approx(bottom_front)

    plane = PlaneView.square(4.0, 400)
    picture = plane.canvas()
    plane.draw_boxes(picture, corners[None], np.array([[255, 0, 0]]), width_px=2)
    # where the drawn segments (12 edges, the front face's cross) cross the middle line
    edges = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7),
             (0, 2), (1, 3)]
    crossings = [heading[0, 0], heading[1, 0]]
    for i, j in edges:
        (xa, ya), (xb, yb) = corners[i, :2], corners[j, :2]
        if (ya - y_mid) * (yb - y_mid) < 0:
            crossings.append(xa + (y_mid - ya) / (yb - ya) * (xb - xa))
    lo, hi = sorted(heading[:, 0])
    checked = {True: 0, False: 0}
    for x in np.arange(-3.0, 3.0, 0.02):
        if min(abs(x - c) for c in crossings) < 0.1:  # 5 px: the edges' width and antialiasing
            continue
        u, v = np.rint(plane.to_pixels([x, y_mid])).astype(int)
        assert v == 199
        on_heading = bool(lo < x < hi)
        assert _drawn(picture, u, v) == on_heading, (x, on_heading)
        checked[on_heading] += 1
    assert checked[True] > 50 and checked[False] > 100


def _one_patch_map(centre_xy, half_m: float):
    """A map whose only shape is a square drivable-area patch (`MapLayers` as `MapLayers.open` builds it)."""
    from nuparquet.map.lookup import _Layer, _Parts
    from nuparquet.map.queries import MapLayers

    empty = np.empty(0, dtype=object)
    layers = {name: _Layer(empty, empty) for name, _, _ in MAP_STYLE}
    x, y = centre_xy
    patch = np.array([shapely.box(x - half_m, y - half_m, x + half_m, y + half_m)], dtype=object)
    layers["drivable_area"] = _Layer(np.array(["patch"], dtype=object), patch)
    return MapLayers("nowhere", layers, {"drivable_area": _Parts(np.zeros(1, np.intp), patch)})


@pytest.mark.parametrize("yaw_deg, expected_plane_xy", [
    (90.0, (10.0, 0.0)),  # the ego faces north: a patch 10 m north is 10 m ahead (x, to the right)
    (-90.0, (-10.0, 0.0)),  # faces south: the patch is behind
    (30.0, (5.0, 8.660254)),  # north is 60° left of the heading: (10 sin 30°, 10 cos 30°)
    (180.0, (0.0, -10.0)),  # faces west: north is to the right (y < 0, down in the picture)
])
def test_a_map_patch_under_a_yawed_ego_frame_lands_where_the_rotation_puts_it(yaw_deg, expected_plane_xy):
    """The map drawn under a plane whose origin is the ego at global (100, 200) and whose x axis points at the yaw:
    a 2 m square patch 10 m north of the ego appears at the plane position worked out by hand above."""
    origin = np.array([100.0, 200.0])
    plane = PlaneView.square(20.0, 400)  # 10 px per metre
    picture = plane.map_canvas(_one_patch_map(origin + [0.0, 10.0], 1.0), origin, np.deg2rad(yaw_deg))
    drawn = np.abs(picture.astype(int) - BACKGROUND).max(axis=2) > 0
    v, u = np.nonzero(drawn)
    assert 300 < len(u) < 500  # 2 m x 2 m at 10 px/m (a rotated square's edge pixels either way)
    centre_px = plane.to_pixels(expected_plane_xy)
    assert np.hypot(u.mean() - centre_px[0], v.mean() - centre_px[1]) < 1.0, (u.mean(), v.mean(), centre_px)
