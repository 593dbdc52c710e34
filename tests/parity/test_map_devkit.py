"""Map queries (`nuparquet.map.queries.MapLayers`) against the devkit's `NuScenesMap` on the synthetic maps:
the same tokens for thousands of random points and patches, the same lane discretisation, pixel-equal masks.

Points mix three kinds: near the roads (node + noise), uniform over the map's extent (mostly off-road), and
exactly on polygon nodes (on a boundary: the devkit's strict `within` says no)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import nuparquet

pytestmark = pytest.mark.devkit


def _points(nusc_map, rng, n):
    xy = np.array([[node["x"], node["y"]] for node in nusc_map.node])
    near = xy[rng.integers(0, len(xy), n // 2)] + rng.normal(0.0, 6.0, (n // 2, 2))
    lo, hi = xy.min(axis=0) - 30.0, xy.max(axis=0) + 30.0
    uniform = rng.uniform(lo, hi, (n // 4, 2))
    on_nodes = xy[rng.integers(0, len(xy), n - n // 2 - n // 4)]
    return np.r_[near, uniform, on_nodes]


@pytest.fixture(scope="module")
def maps(map_out, devkit_maps):
    ours = nuparquet.open(map_out)
    return {location: (devkit_maps[location], ours.map(location)) for location in sorted(devkit_maps)[:2]}


def test_layers_on_point_for_many_points(maps):
    rng = np.random.default_rng(1)
    found = 0
    for nusc_map, ours in maps.values():
        points = _points(nusc_map, rng, 500)
        mine = ours.layers_on_point(points[:, 0], points[:, 1])
        for i, (x, y) in enumerate(points):
            expected = nusc_map.layers_on_point(x, y)
            assert {layer: mine[layer][i] for layer in expected} == expected, (x, y)
            found += sum(v != "" for v in expected.values())
    assert found > 600  # the points do land on the layers


def test_closest_lane_for_many_points(maps):
    rng = np.random.default_rng(2)
    hits = 0
    for nusc_map, ours in maps.values():
        points = _points(nusc_map, rng, 300)
        mine = ours.closest_lane(points[:, 0], points[:, 1], radius_m=5.0)
        expected = [nusc_map.get_closest_lane(x, y, radius=5.0) for x, y in points]
        assert mine.tolist() == expected
        # in blocks of 64 points (the default block holds 4096): each block's answers go to its own points
        assert ours.closest_lane(points[:, 0], points[:, 1], radius_m=5.0, chunk=64).tolist() == expected
        hits += sum(e != "" for e in expected)
        wide = ours.closest_lane(points[:50, 0], points[:50, 1], radius_m=12.5)
        assert wide.tolist() == [nusc_map.get_closest_lane(x, y, radius=12.5) for x, y in points[:50]]
    assert hits > 200


@pytest.mark.parametrize("mode", ["intersect", "within"])
def test_records_in_patch(maps, mode):
    rng = np.random.default_rng(3)
    non_empty = 0
    for nusc_map, ours in maps.values():
        centres = _points(nusc_map, rng, 80)
        for cx, cy in centres:
            hw, hh = rng.uniform(2.0, 120.0, 2)
            box = (cx - hw, cy - hh, cx + hw, cy + hh)
            expected = nusc_map.get_records_in_patch(box, mode=mode)
            assert ours.records_in_patch(box, mode=mode) == expected, box
            non_empty += sum(bool(v) for v in expected.values())
    assert non_empty > 100


def test_discretize_lanes_equals_the_devkit(maps):
    for nusc_map, ours in maps.values():
        tokens = [r["token"] for r in nusc_map.lane[:30] + nusc_map.lane_connector[:10]]
        for resolution in (0.5, 1.3):
            assert ours.discretize_lanes(tokens, resolution) == nusc_map.discretize_lanes(tokens, resolution)


def test_discretize_lanes_names_the_unknown_tokens_the_first_five_then_dots(maps):
    from nuparquet.errors import UsageError

    for location, (_, ours) in maps.items():
        with pytest.raises(UsageError, match=rf"^no lane or lane connector 'nope' in the map of {location}$"):
            ours.discretize_lanes(["nope"], 1.0)
        six = [f"t{i}" for i in range(6)]
        with pytest.raises(UsageError, match=rf"^no lane or lane connector 't0', 't1', 't2', 't3', 't4' \.\.\. in "
                                             rf"the map of {location}$"):
            ours.discretize_lanes(six, 1.0)


def test_map_mask_is_pixel_equal(maps):
    rng = np.random.default_rng(4)
    polygon_layers = ["drivable_area", "road_segment", "road_block", "lane", "ped_crossing", "walkway", "stop_line",
                      "carpark_area"]
    line_layers = ["road_divider", "lane_divider", "traffic_light"]
    painted = 0
    for nusc_map, ours in maps.values():
        nodes = np.array([[node["x"], node["y"]] for node in nusc_map.node])
        for k in range(8):
            cx, cy = nodes[rng.integers(len(nodes))]
            angle = 0.0 if k % 2 == 0 else float(rng.uniform(-180.0, 180.0))
            box = (cx, cy, float(rng.uniform(40.0, 120.0)), float(rng.uniform(40.0, 120.0)))
            canvas = (int(rng.integers(100, 300)), int(rng.integers(100, 300)))
            expected = nusc_map.get_map_mask(box, angle, polygon_layers, canvas)
            assert np.array_equal(ours.map_mask(box, angle, polygon_layers, canvas), expected)
            painted += int(expected.sum())
            try:
                expected_lines = nusc_map.get_map_mask(box, angle, line_layers, canvas)
            except TypeError:  # the devkit cannot iterate a clipped MultiLineString (shapely 2): documented deviation
                continue
            mine = ours.map_mask(box, angle, line_layers, canvas)
            assert mine.shape[0] == 2  # traffic_light has no mask
            assert np.array_equal(mine, expected_lines)
    assert painted > 10_000


def test_an_invalid_drivable_area_polygon_is_painted_and_an_invalid_road_segment_is_not(small_map_root, tmp_path):
    """The devkit's map mask skips invalid polygons (`polygon.is_valid`) of every polygon layer but drivable_area,
    whose polygons it paints whatever their validity. A polygon whose ring touches itself (valid for GEOS's
    intersection, not `is_valid`), far from the rest of the map, named by a drivable area and by a road segment:
    the drivable_area mask shows it, the road_segment mask does not, both pixel for pixel as the devkit's."""
    from nuscenes.map_expansion.map_api import NuScenesMap

    from conftest import SYNTH_VERSION, first_map
    from nuparquet.conversion import convert

    path = first_map(small_map_root)
    data = json.loads(path.read_text())
    x0 = max(n["x"] for n in data["node"]) + 500.0
    y0 = max(n["y"] for n in data["node"]) + 500.0
    ring = [(0.0, 0.0), (20.0, 0.0), (20.0, 20.0), (10.0, 0.0), (0.0, 20.0)]  # (10, 0) lies on the first edge
    nodes = [{"token": f"bad-node-{k}", "x": x0 + x, "y": y0 + y} for k, (x, y) in enumerate(ring)]
    data["node"] += nodes
    data["polygon"].append({"token": "bad-polygon", "exterior_node_tokens": [n["token"] for n in nodes], "holes": []})
    data["drivable_area"].append({"token": "bad-drivable", "polygon_tokens": ["bad-polygon"]})
    data["road_segment"].append(data["road_segment"][0] | {"token": "bad-segment", "polygon_token": "bad-polygon"})
    path.write_text(json.dumps(data))
    convert(small_map_root, SYNTH_VERSION, tmp_path / "out")
    ours = nuparquet.open(tmp_path / "out").map(path.stem)
    nusc_map = NuScenesMap(str(small_map_root), path.stem)
    assert not nusc_map.extract_polygon("bad-polygon").is_valid
    layers = ["drivable_area", "road_segment"]
    for box, angle in (((x0 + 10.0, y0 + 10.0, 30.0, 30.0), 0.0), ((x0 + 8.0, y0 + 12.0, 26.0, 34.0), 25.0)):
        expected = nusc_map.get_map_mask(box, angle, layers, (120, 150))
        assert expected[0].sum() > 500 and expected[1].sum() == 0  # only our polygon is there: painted, skipped
        assert np.array_equal(ours.map_mask(box, angle, layers, (120, 150)), expected)


def test_open_names_what_is_missing(map_out, extract_out):
    import nuparquet
    from nuparquet.errors import UsageError

    with pytest.raises(UsageError, match="no map of 'atlantis'.*maps: boston-seaport"):
        nuparquet.open(map_out).map("atlantis")
    with pytest.raises(UsageError, match="has no map/ datasets"):  # the real extract has no maps/expansion/
        nuparquet.open(extract_out).map("boston-seaport")


def test_closest_lane_ties_go_to_the_later_candidate_as_the_devkit_does(maps):
    """A lane connector starts exactly where its incoming lane ends: at that point both lie at distance 0 (a tie
    at the nearest pose), and the devkit's `<=` scan keeps the later candidate (connectors after lanes)."""
    ties = 0
    for nusc_map, ours in maps.values():
        starts = np.array([nusc_map.arcline_path_3[c["token"]][0]["start_pose"][:2] for c in nusc_map.lane_connector
                           if nusc_map.arcline_path_3.get(c["token"])])
        mine = ours.closest_lane(starts[:, 0], starts[:, 1], radius_m=5.0)
        expected = [nusc_map.get_closest_lane(x, y, radius=5.0) for x, y in starts]
        assert mine.tolist() == expected
        connectors = {c["token"] for c in nusc_map.lane_connector}
        ties += sum(token in connectors for token in expected)
    assert ties > 5  # the tie is really reached: the connector wins over the lane ending at the same point


def test_a_line_node_exactly_on_the_patch_edge_is_not_inside_the_patch(maps):
    """get_records_in_patch keeps a line layer record when one of its nodes lies strictly inside the patch: a node
    exactly on an edge does not count. Tiny patches (1e-6 m) with the node on their left, right, bottom or top edge
    hold no other node, so the edge rule alone decides; a patch around the node holds it."""
    checked = 0
    e = 1e-6
    for nusc_map, ours in maps.values():
        for record in nusc_map.lane_divider[:10]:
            node = nusc_map.get("node", nusc_map.get("line", record["line_token"])["node_tokens"][0])
            x, y = node["x"], node["y"]
            for box, holds in (((x, y - e, x + e, y + e), False), ((x - e, y - e, x, y + e), False),
                               ((x - e, y, x + e, y + e), False), ((x - e, y - e, x + e, y), False),
                               ((x - e, y - e, x + e, y + e), True)):
                for mode in ("intersect", "within"):
                    expected = nusc_map.get_records_in_patch(box, ["lane_divider", "road_segment"], mode=mode)
                    assert ours.records_in_patch(box, ["lane_divider", "road_segment"], mode=mode) == expected
                    assert (record["token"] in expected["lane_divider"]) == (holds and mode == "intersect"), box
                checked += 1
    assert checked >= 20


# --- the helpers by record (issue 24) ------------------------------------------------------------------------------


def test_record_on_point_for_every_polygon_layer(maps):
    rng = np.random.default_rng(4)
    found = 0
    for nusc_map, ours in maps.values():
        for x, y in _points(nusc_map, rng, 60):
            for layer in nusc_map.non_geometric_polygon_layers:
                expected = nusc_map.record_on_point(x, y, layer)
                assert ours.record_on_point(x, y, layer) == expected
                found += expected != ""
    assert found > 60
    with pytest.raises(ValueError, match="road_divider is not a polygon layer"):
        ours.record_on_point(0.0, 0.0, "road_divider")


def test_bounds_of_every_record(maps):
    checked = 0
    for nusc_map, ours in maps.values():
        for layer in nusc_map.non_geometric_polygon_layers + ["road_divider", "lane_divider"]:
            for record in getattr(nusc_map, layer):
                assert ours.bounds(layer, record["token"]) == nusc_map.get_bounds(layer, record["token"])
                checked += 1
    assert checked > 100


def test_next_roads_from_points_on_lanes_blocks_and_segments(maps):
    rng = np.random.default_rng(5)
    answered = refused = non_empty = 0
    for nusc_map, ours in maps.values():
        for x, y in _points(nusc_map, rng, 160):
            try:
                expected = nusc_map.get_next_roads(x, y)
            except AssertionError:  # no road record under the point
                with pytest.raises(ValueError, match="no road_segment, road_block or lane"):
                    ours.next_roads(x, y)
                refused += 1
                continue
            assert ours.next_roads(x, y) == expected, (x, y)
            answered += 1
            non_empty += any(expected.values())
    assert answered > 40 and refused > 10 and non_empty > 20


def test_arcline_paths_and_lane_connectivity(maps):
    for nusc_map, ours in maps.values():
        for record in nusc_map.lane + nusc_map.lane_connector:
            token = record["token"]
            assert ours.arcline_path(token) == nusc_map.get_arcline_path(token)
            assert ours.incoming_lanes(token) == nusc_map.get_incoming_lane_ids(token)
            assert ours.outgoing_lanes(token) == nusc_map.get_outgoing_lane_ids(token)


def test_arcline_helpers_equal_arcline_path_utils(maps):
    from nuscenes.map_expansion import arcline_path_utils as devkit

    from nuparquet.map import arcline

    rng = np.random.default_rng(6)
    curved = 0
    for nusc_map, ours in maps.values():
        for record in nusc_map.lane + nusc_map.lane_connector:
            lane = ours.arcline_path(record["token"])
            assert arcline.length_of_lane(lane) == devkit.length_of_lane(lane)
            start = lane[0]["start_pose"]
            for _ in range(3):
                pose = (start[0] + rng.normal(0, 8), start[1] + rng.normal(0, 8), rng.uniform(-3, 3))
                for resolution in (0.5, 1.0):
                    mine, along = arcline.project_pose_to_lane(pose, lane, resolution)
                    theirs, their_along = devkit.project_pose_to_lane(pose, lane, resolution)
                    assert mine == tuple(theirs) and along == their_along
                distance = rng.uniform(0, devkit.length_of_lane(lane))
                curvature = arcline.curvature_at_distance(distance, lane)
                assert curvature == devkit.get_curvature_at_distance_along_lane(distance, lane)
                curved += curvature > 0
    assert curved > 5  # arcs as well as straight segments


@pytest.mark.parametrize(("distance_m", "expected"), [(1.0, 0.2), (4.0, 0.2), (4.5, 0.0), (1.5, 0.0), (2.5, 0.2), (0.0, 0.2)])
def test_curvature_exactly_at_a_paths_or_segments_end_belongs_to_it_like_the_devkit(distance_m, expected):
    """arcline_path_utils' `_find_index` takes the first cumulative end >= the distance (`<=`): a distance exactly
    at path 0's end (4.0) or at its first segment's end (1.0) is path 0's last / first segment, an arc (1 / 5),
    where a strict `<` would take the straight that follows."""
    from nuscenes.map_expansion import arcline_path_utils as devkit

    from nuparquet.map import arcline

    lane = [{"start_pose": [0.0, 0.0, 0.0], "end_pose": [4.0, 0.0, 0.0], "shape": "LSL", "radius": 5.0,
             "segment_length": [1.0, 1.0, 2.0]},
            {"start_pose": [4.0, 0.0, 0.0], "end_pose": [8.0, 0.0, 0.0], "shape": "SSS", "radius": 10.0,
             "segment_length": [2.0, 1.0, 1.0]}]
    assert devkit.get_curvature_at_distance_along_lane(distance_m, lane) == expected
    assert arcline.curvature_at_distance(distance_m, lane) == expected
