"""`nuparquet.devkit.map_expansion.map_api` against the devkit's own `NuScenesMap` / `NuScenesMapExplorer` on the
generator's maps, ours served from the converted output of a dataroot whose map JSON files were deleted: every
record (key order, types, the shortcuts' shared objects), every attribute, every query with points on boundaries
and inside holes, rotated patches, empty answers, unknown tokens and layers (the devkit's errors)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from nuparquet.devkit.map_expansion.map_api import NuScenesMap, NuScenesMapExplorer

pytestmark = pytest.mark.devkit


@pytest.fixture(scope="session")
def stripped_root(map_root, tmp_path_factory):
    """A copy of the dataroot's maps/ without maps/expansion/: the map JSON files deleted after conversion."""
    root = tmp_path_factory.mktemp("map-face") / "data"
    shutil.copytree(map_root / "maps", root / "maps", ignore=shutil.ignore_patterns("expansion"))
    return root


@pytest.fixture(scope="module")
def pairs(devkit_maps, map_out, stripped_root):
    return {location: (devkit_maps[location], NuScenesMap(str(stripped_root), location, parquet=map_out))
            for location in sorted(devkit_maps)}


def _points(nusc_map, rng, n):
    """Near the roads, uniform over the map, exactly on nodes (a boundary: strictly-within says no), and inside the
    holes (a hole's centroid: within the exterior, outside the polygon)."""
    xy = np.array([[node["x"], node["y"]] for node in nusc_map.node])
    near = xy[rng.integers(0, len(xy), n // 2)] + rng.normal(0.0, 6.0, (n // 2, 2))
    uniform = rng.uniform(xy.min(axis=0) - 30.0, xy.max(axis=0) + 30.0, (n // 4, 2))
    on_nodes = xy[rng.integers(0, len(xy), n - n // 2 - n // 4)]
    holes = [nusc_map.explorer.extract_polygon(p["token"]).interiors[0].centroid.coords[0]
             for p in nusc_map.polygon if any(h["node_tokens"] for h in p["holes"])]
    return np.r_[near, uniform, on_nodes, np.array(holes).reshape(-1, 2)]


def test_construction_reads_the_manifest_only_and_no_json(pairs, stripped_root, map_out, map_root):
    for location, (theirs, ours) in pairs.items():
        assert not (stripped_root / "maps" / "expansion").exists()
        assert ours.json_fname == str(stripped_root / "maps" / "expansion" / f"{location}.json")
        assert ours.dataroot == str(stripped_root) and ours.map_name == location
        assert ours.version == theirs.version and ours.canvas_edge == theirs.canvas_edge
        for name in ("geometric_layers", "non_geometric_polygon_layers", "lookup_polygon_layers",
                     "non_geometric_line_layers", "non_geometric_layers", "layer_names"):
            assert getattr(ours, name) == getattr(theirs, name), name
    fresh = NuScenesMap(str(map_out), "boston-seaport")  # the output as dataroot: the recorded dataroot for files
    assert "lane" not in vars(fresh) and "_token2ind" not in vars(fresh)  # nothing built yet
    assert fresh.dataroot == str(map_root)


def test_every_layer_record_as_the_devkit_holds_it(pairs):
    for theirs, ours in pairs.values():
        for layer in theirs.layer_names + ["arcline_path_3", "connectivity"]:
            mine, expected = getattr(ours, layer), getattr(theirs, layer)
            # json.dumps: key order, int vs float, nesting; == : the values
            assert json.dumps(mine) == json.dumps(expected) and mine == expected, layer
        assert json.dumps(ours.json_obj) == json.dumps(theirs.json_obj)
        assert list(ours.json_obj) == list(theirs.json_obj)


def test_the_shortcuts_share_the_linked_records_objects_as_the_devkits(pairs):
    _, ours = pairs["boston-seaport"]
    lane = ours.lane[0]
    polygon = ours.get("polygon", lane["polygon_token"])
    assert lane["exterior_node_tokens"] is polygon["exterior_node_tokens"] and lane["holes"] is polygon["holes"]
    assert lane["left_lane_divider_segment_nodes"][0] is ours.get("node", lane["left_lane_divider_segments"][0]["node_token"])
    divider = ours.lane_divider[0]
    assert divider["node_tokens"] is ours.get("line", divider["line_token"])["node_tokens"]
    kinds = set()
    for stop in ours.stop_line:
        kinds.add(stop["stop_line_type"])
        linked = ("ped_crossing", "ped_crossing_tokens") if stop["stop_line_type"] == "PED_CROSSING" else \
            ("traffic_light", "traffic_light_tokens")
        assert [id(c) for c in stop["cue"]] == [id(ours.get(linked[0], t)) for t in stop[linked[1]]]
    assert kinds == {"PED_CROSSING", "TRAFFIC_LIGHT"}
    assert ours.get("lane", lane["token"]) is lane  # the same dict on every call


def test_token2ind_is_built_per_layer_on_first_use_and_equals_the_devkits(pairs):
    theirs, ours = pairs["singapore-onenorth"]
    ours = NuScenesMap(str(ours.dataroot), ours.map_name, parquet=ours.parquet)
    index = ours._token2ind
    assert index["node"][theirs.node[3]["token"]] == 3 and dict.keys(index) == {"node"}  # only the layer asked for
    assert index["lane"][theirs.lane[2]["token"]] == 2  # and the layers its records link to (the shortcuts)
    assert dict.keys(index) == {"node", "polygon", "lane"} and "walkway" in index
    assert list(index) == list(theirs._token2ind)  # iterating builds the rest, in the devkit's order
    assert index == theirs._token2ind and dict(index.items()) == theirs._token2ind
    assert index.get("nope") is None and index.get("node") == theirs._token2ind["node"]
    with pytest.raises(KeyError):
        index["nope"]


def test_get_and_getind_with_the_devkits_errors(pairs):
    for theirs, ours in pairs.values():
        for layer in theirs.layer_names:
            for i in (0, len(getattr(theirs, layer)) - 1):
                token = getattr(theirs, layer)[i]["token"]
                assert ours.getind(layer, token) == theirs.getind(layer, token) == i
                assert ours.get(layer, token) == theirs.get(layer, token)
        for call in (theirs.get, ours.get):
            with pytest.raises(AssertionError, match="Layer nope not found"):
                call("nope", "x")
            with pytest.raises(KeyError):
                call("lane", "no-such-token")


def test_explorer_attributes(pairs):
    for theirs, ours in pairs.values():
        ex, dx = ours.explorer, theirs.explorer
        assert isinstance(ex, NuScenesMapExplorer) and ex.map_api is ours
        for name in ("canvas_min_x", "canvas_min_y", "canvas_max_x", "canvas_max_y", "canvas_aspect_ratio",
                     "color_map", "representative_layers"):
            assert getattr(ex, name) == getattr(dx, name), name
        for figsize in (None, 2, 1.5, (3, 4)):
            assert ex._get_figsize(figsize) == dx._get_figsize(figsize)
        for call in (ex._get_figsize, dx._get_figsize):
            with pytest.raises(Exception, match="Invalid figsize"):
                call([3, 4])


def test_layers_on_point_and_record_on_point(pairs):
    rng = np.random.default_rng(11)
    found = 0
    for theirs, ours in pairs.values():
        for x, y in _points(theirs, rng, 70):
            expected = theirs.layers_on_point(x, y)
            assert ours.layers_on_point(x, y) == expected, (x, y)
            # a subset, in the order asked for (the devkit's answer for it is its answer for each layer)
            assert list(ours.layers_on_point(x, y, ["walkway", "lane"]).items()) == \
                [("walkway", expected["walkway"]), ("lane", expected["lane"])]
            assert ours.record_on_point(x, y, "road_segment") == expected["road_segment"]
            found += sum(v != "" for v in expected.values())
        assert ours.layers_on_point(0.0, 0.0, []) == theirs.layers_on_point(0.0, 0.0, []) == {}
        for layer in ("lane_connector", "lane_divider", "nope"):  # the devkit's refusal, lane_connector included
            for call in (theirs.layers_on_point, ours.layers_on_point):
                with pytest.raises(ValueError, match=f"{layer} is not a polygon layer"):
                    call(1.0, 1.0, [layer])
            for call in (theirs.record_on_point, ours.record_on_point):
                with pytest.raises(ValueError, match=f"{layer} is not a polygon layer"):
                    call(1.0, 1.0, layer)
    assert found > 50


def test_a_point_inside_a_hole_is_not_on_the_polygon_but_on_the_one_filling_it(pairs):
    for theirs, ours in pairs.values():
        holed = [p for p in theirs.polygon if any(h["node_tokens"] for h in p["holes"])]
        assert holed  # the generator makes holes
        for polygon in holed:
            x, y = theirs.extract_polygon(polygon["token"]).interiors[0].centroid.coords[0]
            expected = theirs.layers_on_point(x, y)
            assert ours.layers_on_point(x, y) == expected
            owner = [layer for layer in theirs.non_geometric_polygon_layers if layer != "drivable_area"
                     and any(r["polygon_token"] == polygon["token"] for r in getattr(theirs, layer))]
            for layer in owner:
                assert all(ours.get(layer, t)["polygon_token"] != polygon["token"] for t in [expected[layer]] if t)


@pytest.mark.parametrize("mode", ["intersect", "within"])
def test_records_in_patch_and_in_radius(pairs, mode):
    rng = np.random.default_rng(12)
    non_empty = 0
    for theirs, ours in pairs.values():
        for cx, cy in _points(theirs, rng, 16):
            hw, hh = rng.uniform(1.0, 80.0, 2)
            box = (cx - hw, cy - hh, cx + hw, cy + hh)
            expected = theirs.get_records_in_patch(box, mode=mode)
            assert ours.get_records_in_patch(box, mode=mode) == expected, box
            some = ["lane_connector", "lane", "traffic_light"]
            assert ours.get_records_in_patch(box, some, mode) == theirs.get_records_in_patch(box, some, mode)
            assert ours.get_records_in_radius(cx, cy, hw, some, mode) == theirs.get_records_in_radius(cx, cy, hw, some, mode)
            non_empty += sum(bool(v) for v in expected.values())
        far = (-1e6, -1e6, -1e6 + 5, -1e6 + 5)  # nothing there: every layer, empty
        assert ours.get_records_in_patch(far, mode=mode) == theirs.get_records_in_patch(far, mode=mode)
        assert set(map(len, ours.get_records_in_patch(far, mode=mode).values())) == {0}
        assert ours.get_records_in_patch(far, [], mode) == theirs.get_records_in_patch(far, [], mode) == {}
        for call in (theirs.get_records_in_patch, ours.get_records_in_patch):
            with pytest.raises(ValueError, match="node is not a valid layer"):
                call(far, ["lane", "node"], mode)
            with pytest.raises(AttributeError, match="no attribute 'nope'"):
                call(far, ["nope"], mode)
            with pytest.raises(ValueError, match="Mode inside is not valid"):
                call(far, None, "inside")
    assert non_empty > 50


def test_is_record_in_patch(pairs):
    theirs, ours = pairs["boston-seaport"]
    rng = np.random.default_rng(13)
    for layer in theirs.lookup_polygon_layers + theirs.non_geometric_line_layers:
        for record in getattr(theirs, layer)[:4]:
            x1, y1, x2, y2 = theirs.get_bounds(layer, record["token"]) if layer != "lane_connector" else (0, 0, 1, 1)
            for box in [(x1, y1, x2, y2), (x1 - 1, y1 - 1, x2 + 1, y2 + 1), tuple(rng.uniform(0, 2000, 4))]:
                for mode in ("intersect", "within"):
                    assert ours.is_record_in_patch(layer, record["token"], box, mode) == \
                        theirs.is_record_in_patch(layer, record["token"], box, mode)
    for call in (theirs.is_record_in_patch, ours.is_record_in_patch):
        with pytest.raises(ValueError, match="node is not a valid layer"):
            call("node", theirs.node[0]["token"], (0, 0, 1, 1))


def _patches(theirs, rng, n):
    xy = np.array([[node["x"], node["y"]] for node in theirs.node])
    centres = xy[rng.integers(0, len(xy), n)] + rng.normal(0, 5, (n, 2))
    angles = np.r_[0.0, 90.0, -45.0, rng.uniform(-180, 180, n - 3)]
    sizes = rng.uniform(10, 120, (n, 2))
    return [((cx, cy, h, w), a) for (cx, cy), a, (h, w) in zip(centres, angles, sizes)]


def test_map_mask_is_pixel_equal_with_angles_sizes_and_layer_subsets(pairs):
    rng = np.random.default_rng(14)
    painted = 0
    for theirs, ours in pairs.values():
        for patch_box, angle in _patches(theirs, rng, 12):
            for layers, canvas in ((None, (100, 100)), (["lane", "drivable_area", "walkway"], (73, 151)),
                                   (["road_divider", "traffic_light", "ped_crossing"], None)):
                try:
                    expected = theirs.get_map_mask(patch_box, angle, layers, canvas)
                except TypeError:  # the devkit iterating a MultiLineString (shapely 2): see the next test
                    continue
                mine = ours.get_map_mask(patch_box, angle, layers, canvas)
                assert mine.dtype == expected.dtype == np.uint8 and mine.shape == expected.shape
                assert np.array_equal(mine, expected), (patch_box, angle, layers)
                painted += int(expected.sum() > 0)
        whole = theirs.get_map_mask(None, 0.0, ["drivable_area", "lane"], (50, 80))
        assert np.array_equal(ours.get_map_mask(None, 0.0, ["drivable_area", "lane"], (50, 80)), whole)
        for call in (theirs.get_map_mask, ours.get_map_mask):
            with pytest.raises(ValueError, match="nope is not a valid layer"):
                call((0, 0, 10, 10), 0.0, ["nope"])
            with pytest.raises(AssertionError):  # traffic_light alone: no mask at all, the devkit's assert
                call((0, 0, 10, 10), 0.0, ["traffic_light"])
    assert painted > 30


def test_a_line_clipped_in_two_is_drawn_where_the_devkit_raises(pairs):
    """A divider crossing a patch's corner twice clips to a MultiLineString: the devkit's `for line in lines`
    raises TypeError (shapely 2); ours draws each part, as the devkit's own step for one LineString draws it."""
    theirs, ours = pairs["boston-seaport"]
    line = theirs.extract_line(theirs.lane_divider[0]["line_token"])
    x, y = np.asarray(line.coords)[len(line.coords) // 2]
    found = None
    for half in np.linspace(0.5, 8, 40):  # a thin patch across the line's middle: both ends stick out
        for angle in (0.0, 30.0, 60.0, 90.0, 120.0, 150.0):
            geom = dict(theirs.get_map_geom((x, y, 2 * half, 4 * half), angle, ["lane_divider"]))["lane_divider"]
            if any(g.geom_type == "MultiLineString" for g in geom):
                found = ((x, y, 2 * half, 4 * half), angle)
                break
        if found:
            break
    assert found, "no patch clips a divider in two"
    patch_box, angle = found
    with pytest.raises(TypeError):
        theirs.get_map_mask(patch_box, angle, ["lane_divider"], (64, 64))
    mine = ours.get_map_mask(patch_box, angle, ["lane_divider"], (64, 64))
    expected = np.zeros((64, 64), np.uint8)
    from shapely import affinity
    for g in dict(theirs.get_map_geom(patch_box, angle, ["lane_divider"]))["lane_divider"]:
        clip = g.intersection(theirs.explorer.get_patch_coord((0.0, 0.0, patch_box[2], patch_box[3])))
        if clip.is_empty:
            continue
        clip = affinity.affine_transform(clip, [1.0, 0.0, 0.0, 1.0, patch_box[3] / 2.0, patch_box[2] / 2.0])
        clip = affinity.scale(clip, xfact=64 / patch_box[3], yfact=64 / patch_box[2], origin=(0, 0))
        for part in getattr(clip, "geoms", [clip]):
            theirs.explorer.mask_for_lines(part, expected)
    assert expected.sum() > 0 and np.array_equal(mine[0], expected)


def test_map_geom_and_the_geometry_steps_equal_the_devkits(pairs):
    rng = np.random.default_rng(15)
    for theirs, ours in pairs.values():
        ex, dx = ours.explorer, theirs.explorer
        for patch_box, angle in _patches(theirs, rng, 6):
            expected = dx.get_map_geom(patch_box, angle, None)
            mine = ex.get_map_geom(patch_box, angle, None)
            assert [name for name, _ in mine] == [name for name, _ in expected]  # traffic_light left out
            for (name, geoms), (_, theirs_geoms) in zip(mine, expected):
                assert [g.geom_type for g in geoms] == [g.geom_type for g in theirs_geoms], name
                assert all(a.equals_exact(b, 0.0) for a, b in zip(geoms, theirs_geoms)), name
            for name in ("drivable_area", "lane", "walkway"):
                a, b = ex._get_layer_polygon(patch_box, angle, name), dx._get_layer_polygon(patch_box, angle, name)
                assert len(a) == len(b) and all(p.equals_exact(q, 0.0) for p, q in zip(a, b))
                local = (0.0, 0.0, patch_box[2], patch_box[3])
                assert np.array_equal(ex._layer_geom_to_mask(name, a, local, (60, 40)),
                                      dx._layer_geom_to_mask(name, b, local, (60, 40)))
                assert np.array_equal(ex._polygon_geom_to_mask(a, local, name, (60, 40)),
                                      dx._polygon_geom_to_mask(b, local, name, (60, 40)))
            a, b = ex._get_layer_line(patch_box, angle, "road_divider"), dx._get_layer_line(patch_box, angle, "road_divider")
            assert len(a) == len(b) and all(p.equals_exact(q, 0.0) for p, q in zip(a, b))
            assert ex._get_layer_line(patch_box, angle, "traffic_light") is None
            assert ex._get_layer_geom(patch_box, angle, "lane")[:1] == dx._get_layer_geom(patch_box, angle, "lane")[:1]
            assert ex.get_patch_coord(patch_box, angle).equals_exact(dx.get_patch_coord(patch_box, angle), 0.0)
            assert ex._line_geom_to_mask([], local, "traffic_light", (5, 5)) is None
            assert np.array_equal(ex.map_geom_to_mask(mine, local, (30, 20)), dx.map_geom_to_mask(expected, local, (30, 20)))
        for step, layer, message in ((ex._get_layer_polygon, "road_divider", "is not a polygonal layer"),
                                     (ex._get_layer_line, "lane", "is not a line layer"),
                                     (ex._get_layer_geom, "node", "is not a valid layer")):
            with pytest.raises(ValueError, match=message):
                step((0, 0, 1, 1), 0.0, layer)


def test_extract_polygon_line_and_bounds_of_every_record(pairs):
    for theirs, ours in pairs.values():
        for record in theirs.polygon:
            assert ours.extract_polygon(record["token"]).equals_exact(theirs.extract_polygon(record["token"]), 0.0)
        for record in theirs.line:
            assert ours.extract_line(record["token"]).equals_exact(theirs.extract_line(record["token"]), 0.0)
        for layer in theirs.non_geometric_layers:
            for record in getattr(theirs, layer):
                expected = theirs.get_bounds(layer, record["token"])
                mine = ours.get_bounds(layer, record["token"])
                assert mine == expected and [type(v) for v in mine] == [type(v) for v in expected], layer
        for call in (theirs.get_bounds, ours.get_bounds):
            with pytest.raises(ValueError, match="lane_connector is not a valid layer"):
                call("lane_connector", theirs.lane_connector[0]["token"])
            with pytest.raises(KeyError):
                call("lane", "no-such-token")
        for call in (theirs.extract_polygon, ours.extract_polygon):
            with pytest.raises(KeyError):
                call("no-such-token")


def test_lanes_arclines_connectivity_and_closest_lane(pairs):
    rng = np.random.default_rng(16)
    for theirs, ours in pairs.values():
        lanes = [r["token"] for r in theirs.lane + theirs.lane_connector]
        for token in lanes:
            assert ours.get_arcline_path(token) == theirs.get_arcline_path(token)
            assert ours.get_outgoing_lane_ids(token) == theirs.get_outgoing_lane_ids(token)
            assert ours.get_incoming_lane_ids(token) == theirs.get_incoming_lane_ids(token)
        for call in (theirs.get_arcline_path, ours.get_arcline_path):
            with pytest.raises(ValueError, match="does not have a valid arcline path"):
                call("no-such-lane")
        for call in (theirs.get_outgoing_lane_ids, theirs.get_incoming_lane_ids, ours.get_outgoing_lane_ids,
                     ours.get_incoming_lane_ids):
            with pytest.raises(ValueError, match="no-such-lane is not a valid lane"):
                call("no-such-lane")
        tokens = lanes[:25] + ["no-such-lane"]  # a token without paths: [] as the devkit's
        for resolution in (0.5, 2.0, 10.0):
            mine, expected = ours.discretize_lanes(tokens, resolution), theirs.discretize_lanes(tokens, resolution)
            assert list(mine) == list(expected) and mine["no-such-lane"] == []
            for token in tokens:
                assert len(mine[token]) == len(expected[token])
                np.testing.assert_allclose(np.array(mine[token]).reshape(-1, 3),
                                           np.array(expected[token]).reshape(-1, 3), rtol=0, atol=1e-9)
            lines, theirs_lines = ours.discretize_centerlines(resolution), theirs.discretize_centerlines(resolution)
            assert len(lines) == len(theirs_lines)
            for a, b in zip(lines, theirs_lines):
                assert a.shape == b.shape and a.dtype == b.dtype
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
        for x, y in _points(theirs, rng, 30):
            for radius in (0.5, 15.0):
                assert ours.get_closest_lane(x, y, radius) == theirs.get_closest_lane(x, y, radius)
        assert ours.get_closest_lane(-1e6, -1e6) == theirs.get_closest_lane(-1e6, -1e6) == ""


def test_next_roads_from_lanes_blocks_and_segments(pairs):
    kinds = set()
    for theirs, ours in pairs.values():
        for layer in ("lane", "road_block", "road_segment"):
            for record in getattr(theirs, layer)[:6]:
                x, y = theirs.extract_polygon(record["polygon_token"]).representative_point().coords[0]
                expected = theirs.get_next_roads(x, y)
                assert ours.get_next_roads(x, y) == expected
                kinds.add(next(name for name in ("lane", "road_block", "road_segment")
                               if theirs.layers_on_point(x, y)[name]))
        for call in (theirs.get_next_roads, ours.get_next_roads):
            with pytest.raises(AssertionError, match="No suitable layer"):
                call(-1e6, -1e6)
    assert kinds >= {"lane"}


def test_a_pickled_map_reopens_the_same_output(pairs):
    import pickle

    theirs, ours = pairs["boston-seaport"]
    copy = pickle.loads(pickle.dumps(ours))
    assert copy is not ours and copy.dataroot == ours.dataroot and copy.parquet == ours.parquet
    x, y = theirs.node[0]["x"], theirs.node[0]["y"]
    assert copy.lane == theirs.lane and copy.get_closest_lane(x, y) == theirs.get_closest_lane(x, y)


def test_an_output_without_the_map_is_refused_naming_the_maps_it_holds(map_root, tmp_path):
    from conftest import SYNTH_VERSION

    from nuparquet.conversion import convert
    from nuparquet.errors import UsageError

    out = tmp_path / "no-map"
    convert(map_root, SYNTH_VERSION, out, no_map=True)
    with pytest.raises(UsageError) as caught:
        NuScenesMap(str(out), "boston-seaport")
    assert str(caught.value).endswith(" holds no map of 'boston-seaport' (maps: none): convert a dataroot whose "
                                      "maps/expansion/ holds it")


def test_a_map_mask_of_a_map_of_unknown_size_raises_the_devkits_exception(pairs, monkeypatch):
    """The explorer's map sizes are the devkit's four: a map renamed to none of them raises its message."""
    theirs, ours = pairs["boston-seaport"]
    messages = []
    for nusc_map in (theirs, ours):
        monkeypatch.setattr(nusc_map.explorer.map_api, "map_name", "nowhere")
        with pytest.raises(Exception) as caught:
            nusc_map.explorer.get_map_mask(None, 0.0, ["drivable_area"])
        messages.append(str(caught.value))
    assert messages == ["Error: Invalid map!"] * 2
