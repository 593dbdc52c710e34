"""`nuparquet.devkit.map_expansion.arcline_path_utils` against the devkit's module, function by function, on every
arcline path of the generator's maps (and shapes and distances at the edges): Python types as the devkit's, numbers
within 1e-9 m / 1e-12 rad (numpy's trigonometry for `math`'s: CONTRACTS.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from nuscenes.map_expansion import arcline_path_utils as theirs

from nuparquet.devkit.map_expansion import arcline_path_utils as ours

pytestmark = pytest.mark.devkit
CLOSE = dict(rtol=0, atol=1e-9)


@pytest.fixture(scope="module")
def lanes(devkit_maps):
    return [lane for nusc_map in devkit_maps.values() for lane in nusc_map.arcline_path_3.values() if lane]


def _outcome(call, *args):
    """The value, or the type of the exception (the devkit's `min()` of nothing where the rounding of its sums puts
    a distance past the last segment's end)."""
    try:
        return call(*args)
    except ValueError as error:
        return type(error)


def _same_pose(a, b):
    assert type(a) is tuple and len(a) == len(b) == 3 and all(type(v) is float for v in a)
    np.testing.assert_allclose(a, b, **CLOSE)


def test_every_function_of_the_devkits_module_is_here():
    public = {name for name in vars(theirs) if callable(getattr(theirs, name)) and not name.startswith("__")
              and getattr(getattr(theirs, name), "__module__", "") == theirs.__name__}
    assert public <= set(vars(ours)), public - set(vars(ours))
    assert ours.Pose == theirs.Pose and ours.ArcLinePath == theirs.ArcLinePath


@pytest.mark.parametrize("angle", [0.0, math.pi, -math.pi, 3 * math.pi, -7.5, 1e-17, 2 * math.pi - 1e-15, 100.0])
def test_principal_value(angle):
    assert ours.principal_value(angle) == theirs.principal_value(angle)
    assert type(ours.principal_value(angle)) is float


@pytest.mark.parametrize("shape", ["LRL", "LSL", "LSR", "RLR", "RSL", "RSR", "XYZ"])
def test_segment_signs_and_lie_algebra(shape):
    path = {"shape": shape, "radius": 7.5}
    assert ours.compute_segment_sign(path) == theirs.compute_segment_sign(path)
    assert all(type(v) is int for v in ours.compute_segment_sign(path))
    sign = theirs.compute_segment_sign(path)
    assert ours._get_lie_algebra(sign, 7.5) == theirs._get_lie_algebra(sign, 7.5)


@pytest.mark.parametrize("pose", [(1.0, 0.0, 0.0), (1.0, 0.0, 1e-7), (1.0, 0.0, -0.2), (0.3, -0.7, 0.05)])
@pytest.mark.parametrize("step", [0.0, 0.5, 13.25])
def test_transformation_at_step_and_its_application(pose, step):
    _same_pose(ours.get_transformation_at_step(pose, step), theirs.get_transformation_at_step(pose, step))
    start = (10.0, -4.0, 3.0)
    t = theirs.get_transformation_at_step(pose, step)
    _same_pose(ours.apply_affine_transformation(start, t), theirs.apply_affine_transformation(start, t))


def test_pose_at_length_along_each_segment_and_beyond_the_end(lanes):
    for lane in lanes[:40]:
        for path in lane:
            total = sum(path["segment_length"])
            ends = np.cumsum(path["segment_length"]).tolist()
            for pos in [1e-6, ends[0], ends[1], total / 3, total, total + 5.0]:
                _same_pose(ours.pose_at_length(path, pos), theirs.pose_at_length(path, pos))
    with pytest.raises(AssertionError):
        ours.pose_at_length(lanes[0][0], 0.0)


def test_discretize_lengths_projection_and_curvature_of_every_lane(lanes):
    rng = np.random.default_rng(3)
    for lane in lanes[::2]:  # every other lane of both maps (~100): arcs, straights and connectors
        for resolution in (0.5, 3.0):
            mine, expected = ours.discretize_lane(lane, resolution), theirs.discretize_lane(lane, resolution)
            assert len(mine) == len(expected)
            for a, b in zip(mine, expected):
                _same_pose(a, b)
        path = lane[0]
        assert len(ours.discretize(path, 1.0)) == len(theirs.discretize(path, 1.0))
        np.testing.assert_allclose(ours.discretize(path, 1.0), theirs.discretize(path, 1.0), **CLOSE)
        assert ours.length_of_lane(lane) == theirs.length_of_lane(lane)
        x, y, _ = lane[0]["start_pose"]
        query = (x + rng.normal(0, 3), y + rng.normal(0, 3), 0.0)
        (pose_a, along_a), (pose_b, along_b) = ours.project_pose_to_lane(query, lane), \
            theirs.project_pose_to_lane(query, lane)
        _same_pose(pose_a, pose_b)
        assert along_a == along_b
        total = theirs.length_of_lane(lane)
        ends = np.cumsum([sum(p["segment_length"]) for p in lane]).tolist()
        for distance in [0.0, total / 2, total] + ends:  # exactly at a path's end: that path's, as the devkit's
            assert _outcome(ours.get_curvature_at_distance_along_lane, distance, lane) == \
                _outcome(theirs.get_curvature_at_distance_along_lane, distance, lane)
        assert ours._find_index(ends[0], ends) == theirs._find_index(ends[0], ends)
    with pytest.raises(ValueError):  # beyond the end: the devkit's min() of nothing
        theirs.get_curvature_at_distance_along_lane(total + 1.0, lane)
    with pytest.raises(ValueError):
        ours.get_curvature_at_distance_along_lane(total + 1.0, lane)
    assert ours.discretize_lane([], 0.5) == theirs.discretize_lane([], 0.5) == []
