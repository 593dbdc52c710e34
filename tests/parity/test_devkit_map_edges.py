"""The devkit map face on a map edited to reach the edges the generator's maps do not: an empty hole (the devkit
drops it), a divider whose line has no nodes (skipped by the devkit's geometry and patch tests), stop lines of the
kinds without a cue, two lanes meeting at one node and flowing into one lane (two incoming lanes), an invalid
walkway (skipped by the masks, as the devkit skips it) and a node whose coordinates the JSON wrote as integers.
The devkit reads the edited JSON; ours its conversion, after the JSON is deleted."""

from __future__ import annotations

import json

import numpy as np
import pytest

from nuparquet.devkit.map_expansion.map_api import NuScenesMap

pytestmark = pytest.mark.devkit


@pytest.fixture(scope="module")
def edited(tiny_map_root, tmp_path_factory):
    import shutil

    from nuscenes.map_expansion.map_api import NuScenesMap as DevkitMap

    from conftest import SYNTH_VERSION, first_map
    from nuparquet.conversion import convert

    root = tmp_path_factory.mktemp("map-edges") / "data"
    shutil.copytree(tiny_map_root, root)
    path = first_map(root)
    data = json.loads(path.read_text())
    x0 = max(n["x"] for n in data["node"]) + 300.0
    y0 = max(n["y"] for n in data["node"]) + 300.0

    def node(token, x, y):
        data["node"].append({"token": token, "x": x, "y": y})
        return token

    # two square lanes meeting at one corner node (x0 + 20, y0 + 20), flowing into a third
    shared = node("edge-shared", int(x0) + 20, int(y0) + 20)  # integer coordinates, as some JSON writers give
    x0, y0 = float(int(x0)), float(int(y0))
    a = [node("edge-a0", x0, y0), node("edge-a1", x0 + 20, y0), shared, node("edge-a3", x0, y0 + 20)]
    b = [shared, node("edge-b1", x0 + 40, y0 + 20), node("edge-b2", x0 + 40, y0 + 40), node("edge-b3", x0 + 20, y0 + 40)]
    hole = [node("edge-h0", x0 + 5, y0 + 5), node("edge-h1", x0 + 10, y0 + 5), node("edge-h2", x0 + 10, y0 + 10)]
    data["polygon"] += [
        {"token": "edge-poly-a", "exterior_node_tokens": a, "holes": [{"node_tokens": hole}, {"node_tokens": []}]},
        {"token": "edge-poly-b", "exterior_node_tokens": b, "holes": []},
    ]
    template = data["lane"][0]
    first = data["lane"][0]["token"]
    for token, polygon in (("edge-lane-a", "edge-poly-a"), ("edge-lane-b", "edge-poly-b")):
        data["lane"].append(template | {"token": token, "polygon_token": polygon})
        data["connectivity"][token] = {"incoming": [], "outgoing": [first]}
        data["arcline_path_3"][token] = data["arcline_path_3"][first]
    data["connectivity"][first]["incoming"] = data["connectivity"][first]["incoming"] + ["edge-lane-a", "edge-lane-b"]
    # an invalid walkway (its ring touches itself) over the lanes
    bow = [node(f"edge-w{k}", x0 + x, y0 + y) for k, (x, y) in
           enumerate([(0.0, 0.0), (40.0, 0.0), (40.0, 40.0), (20.0, 0.0), (0.0, 40.0)])]
    data["polygon"].append({"token": "edge-poly-bow", "exterior_node_tokens": bow, "holes": []})
    data["walkway"].append({"token": "edge-walkway", "polygon_token": "edge-poly-bow"})
    data["drivable_area"].append({"token": "edge-drivable", "polygon_tokens": ["edge-poly-bow", "edge-poly-a"]})
    # a divider without nodes, stop lines without cues
    data["line"].append({"token": "edge-line-empty", "node_tokens": []})
    data["lane_divider"].append(data["lane_divider"][0] | {"token": "edge-divider", "line_token": "edge-line-empty"})
    for kind in ("STOP_SIGN", "YIELD"):
        data["stop_line"].append(data["stop_line"][0] | {"token": f"edge-stop-{kind}", "stop_line_type": kind,
                                                         "polygon_token": "edge-poly-b"})
    path.write_text(json.dumps(data))
    devkit_map = DevkitMap(str(root), path.stem)
    out = tmp_path_factory.mktemp("map-edges-out") / "out"
    convert(root, SYNTH_VERSION, out)
    path.unlink()  # the JSON deleted after conversion
    return devkit_map, NuScenesMap(str(root), path.stem, parquet=out), (x0, y0)


def test_every_record_and_index_as_the_devkit_holds_them(edited):
    theirs, ours, _ = edited
    for layer in theirs.layer_names + ["arcline_path_3", "connectivity"]:
        assert json.dumps(getattr(ours, layer)) == json.dumps(getattr(theirs, layer)), layer
    assert type(ours.get("node", "edge-shared")["x"]) is int
    assert ours._token2ind == theirs._token2ind
    assert ours.get("stop_line", "edge-stop-STOP_SIGN")["cue"] == [] == ours.get("stop_line", "edge-stop-YIELD")["cue"]


def test_an_empty_hole_is_dropped_and_a_line_without_nodes_is_empty(edited):
    theirs, ours, _ = edited
    polygon = ours.extract_polygon("edge-poly-a")
    assert polygon.equals_exact(theirs.extract_polygon("edge-poly-a"), 0.0) and len(polygon.interiors) == 1
    assert ours.extract_line("edge-line-empty").is_empty and theirs.extract_line("edge-line-empty").is_empty
    for mode in ("intersect", "within"):
        assert ours.is_record_in_patch("lane_divider", "edge-divider", (-1e9, -1e9, 1e9, 1e9), mode) is \
            theirs.is_record_in_patch("lane_divider", "edge-divider", (-1e9, -1e9, 1e9, 1e9), mode)


def test_two_lanes_meeting_at_one_node(edited):
    theirs, ours, (x0, y0) = edited
    first = theirs.lane[0]["token"]
    assert ours.get_incoming_lane_ids(first) == theirs.get_incoming_lane_ids(first)
    assert ours.get_incoming_lane_ids(first)[-2:] == ["edge-lane-a", "edge-lane-b"]
    corner = (x0 + 20, y0 + 20)
    assert ours.layers_on_point(*corner) == theirs.layers_on_point(*corner)
    assert ours.layers_on_point(*corner)["lane"] == ""  # on both boundaries: in neither (strictly within)
    inside_hole = (x0 + 8, y0 + 6)
    assert ours.layers_on_point(*inside_hole) == theirs.layers_on_point(*inside_hole)
    touching = (corner[0], corner[1], corner[0] + 5, corner[1] + 5)  # meets lane a at its corner node only
    for mode in ("intersect", "within"):
        assert ours.get_records_in_patch(touching, mode=mode) == theirs.get_records_in_patch(touching, mode=mode)
    assert {"edge-lane-a", "edge-lane-b"} <= set(ours.get_records_in_patch(touching)["lane"])
    assert ours.get_closest_lane(*corner, 3.0) == theirs.get_closest_lane(*corner, 3.0)
    assert ours.get_bounds("lane", "edge-lane-b") == theirs.get_bounds("lane", "edge-lane-b")


@pytest.mark.parametrize("angle", [0.0, 45.0, -120.0])
def test_masks_and_geometry_over_the_edits(edited, angle):
    theirs, ours, (x0, y0) = edited
    patch_box = (x0 + 20, y0 + 20, 50.0, 46.0)
    layers = ["drivable_area", "lane", "walkway", "stop_line", "lane_divider"]
    expected = theirs.get_map_mask(patch_box, angle, layers, (100, 92))
    mine = ours.get_map_mask(patch_box, angle, layers, (100, 92))
    assert np.array_equal(mine, expected)
    assert expected[0].sum() > 0 and expected[2].sum() == 0  # the invalid walkway: in drivable_area, not walkway
    for (name, geoms), (_, theirs_geoms) in zip(ours.get_map_geom(patch_box, angle, layers),
                                                theirs.get_map_geom(patch_box, angle, layers)):
        assert len(geoms) == len(theirs_geoms) and all(a.equals_exact(b, 0.0) for a, b in zip(geoms, theirs_geoms))


def test_the_devkits_map_utils_on_ours(pairs_for_utils):
    """`map_expansion.utils` on our map gives the devkit's: the ego poses' drivable ratio, its assertion on a map of
    several separate road graphs (the generator's), and the index rebuilt after records are dropped."""
    from nuscenes.map_expansion import utils as devkit_utils

    from nuparquet.devkit.map_expansion import utils

    theirs, ours, nusc, devkit_nusc = pairs_for_utils
    ratios = []
    for scene in devkit_nusc.scene:
        if devkit_nusc.get("log", scene["log_token"])["location"] == ours.map_name:
            ratios.append(utils.get_egoposes_on_drivable_ratio(nusc, ours, scene["token"]))
            assert ratios[-1] == devkit_utils.get_egoposes_on_drivable_ratio(devkit_nusc, theirs, scene["token"])
    assert ratios and max(ratios) > 0
    for module, nusc_map in ((utils, ours), (devkit_utils, theirs)):
        with pytest.raises(AssertionError, match="Bad initialization"):
            module.get_disconnected_lanes(nusc_map)
        with pytest.raises(AssertionError, match="Bad initialization"):
            module.get_disconnected_subtrees(nusc_map.connectivity)
    index = ours._token2ind
    for nusc_map in (ours, theirs):  # what drop_disconnected_lanes does to the records, then its index call
        nusc_map.lane = nusc_map.lane[2:]
        del nusc_map.connectivity[next(iter(nusc_map.connectivity))]
        nusc_map._make_token2ind()
    assert ours._token2ind is not index and ours._token2ind == theirs._token2ind
    assert ours.get("lane", theirs.lane[0]["token"]) is ours.lane[0]


@pytest.fixture
def pairs_for_utils(map_root, map_out, devkit):
    """Fresh maps (the drop changes them) of a location with two roads, and both NuScenes."""
    from nuscenes.map_expansion.map_api import NuScenesMap as DevkitMap

    from conftest import SYNTH_VERSION
    from nuparquet.devkit import NuScenes

    devkit_nusc = devkit.NuScenes(SYNTH_VERSION, str(map_root), verbose=False)
    location = "boston-seaport"
    return (DevkitMap(str(map_root), location), NuScenesMap(str(map_out), location),
            NuScenes(SYNTH_VERSION, str(map_out), verbose=False), devkit_nusc)


def test_drop_disconnected_lanes(edited):
    """`drop_disconnected_lanes` on a graph made one piece (the generator's roads are separate graphs, which the
    devkit's helper refuses) but for an isolated lane and a link to a lane that is no record: the devkit's on a copy
    of its map and ours on a fresh one drop the same, leaving the same records and index."""
    import copy

    from nuscenes.map_expansion import utils as devkit_utils

    from nuparquet.devkit.map_expansion import utils

    theirs = copy.deepcopy(edited[0])
    ours = NuScenesMap(edited[1].dataroot, edited[1].map_name, parquet=edited[1].parquet)
    for nusc_map in (theirs, ours):  # the same edits in memory on both
        lanes = list(nusc_map.connectivity)
        for a, b in zip(lanes, lanes[1:]):
            nusc_map.connectivity[a]["outgoing"] = nusc_map.connectivity[a]["outgoing"] + [b]
        nusc_map.connectivity[lanes[0]]["incoming"] = nusc_map.connectivity[lanes[0]]["incoming"] + ["ghost"]
        nusc_map.lane.append(dict(nusc_map.lane[0], token="isolated"))
        nusc_map.connectivity["isolated"] = {"incoming": [], "outgoing": []}
        nusc_map._make_token2ind()
    expected = devkit_utils.get_disconnected_lanes(theirs)
    assert utils.get_disconnected_lanes(ours) == expected == ["ghost", "isolated"]
    devkit_utils.drop_disconnected_lanes(theirs)
    assert utils.drop_disconnected_lanes(ours) is ours
    for layer in ("lane", "lane_connector", "connectivity", "arcline_path_3"):
        assert json.dumps(getattr(ours, layer)) == json.dumps(getattr(theirs, layer)), layer
    assert "isolated" not in ours._token2ind["lane"] and ours._token2ind == theirs._token2ind
