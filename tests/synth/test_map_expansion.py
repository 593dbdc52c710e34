"""The synthetic map expansion: the devkit loads it, and it agrees with the scenes drawn on it (ego poses on
lanes of the drivable area, pedestrians on walkways, parked cars off the lanes)."""

from __future__ import annotations

import json

import numpy as np

from nuparquet.synth import synthesize
from tests.conftest import SYNTH_VERSION


def _table(root, name):
    return json.loads((root / SYNTH_VERSION / f"{name}.json").read_text())


def test_every_location_has_a_v13_map_with_every_layer(map_root, devkit_maps):
    logs = _table(map_root, "log")
    assert sorted(devkit_maps) == sorted({log["location"] for log in logs})
    for location, nusc_map in devkit_maps.items():
        assert nusc_map.version == "1.3"
        for layer in nusc_map.non_geometric_layers + ["lane_connector"]:
            assert getattr(nusc_map, layer), f"{location}: {layer} is empty"
        assert set(nusc_map.connectivity) == {r["token"] for r in nusc_map.lane + nusc_map.lane_connector}
        assert set(nusc_map.arcline_path_3) == set(nusc_map.connectivity)
        holes = [h for p in nusc_map.polygon for h in p["holes"]]
        assert holes, "the drivable area has a hole somewhere"
        # The end pose of every arcline path is where the devkit's discretisation ends (the paths are consistent).
        from nuscenes.map_expansion.arcline_path_utils import discretize
        for paths in list(nusc_map.arcline_path_3.values())[:40]:
            for path in paths:
                end = np.array(discretize(path, 0.5)[-1])
                assert np.allclose(end[:2], path["end_pose"][:2], atol=1e-6)


def test_ego_poses_lie_on_drivable_lanes_and_pedestrians_on_walkways(map_root, devkit_maps):
    logs = {r["token"]: r["location"] for r in _table(map_root, "log")}
    scenes = _table(map_root, "scene")
    samples = _table(map_root, "sample")
    sample_data = _table(map_root, "sample_data")
    poses = {r["token"]: r for r in _table(map_root, "ego_pose")}
    scene_location = {s["token"]: logs[s["log_token"]] for s in scenes}
    sample_location = {s["token"]: scene_location[s["scene_token"]] for s in samples}
    checked = 0
    for sd in sample_data[::7]:
        if not sd["is_key_frame"]:
            continue
        x, y, _ = poses[sd["ego_pose_token"]]["translation"]
        nusc_map = devkit_maps[sample_location[sd["sample_token"]]]
        on = nusc_map.layers_on_point(x, y)
        assert on["drivable_area"] and on["road_segment"] and on["walkway"] == "", on
        lanes = nusc_map.get_records_in_patch((x - 0.01, y - 0.01, x + 0.01, y + 0.01), ["lane", "lane_connector"])
        assert lanes["lane"] or lanes["lane_connector"], (x, y)
        checked += 1
    assert checked > 5
    categories = {r["token"]: r["name"] for r in _table(map_root, "category")}
    instances = {r["token"]: categories[r["category_token"]] for r in _table(map_root, "instance")}
    walking = {"human.pedestrian.adult", "human.pedestrian.child"}
    on_walkway = total = 0
    for ann in _table(map_root, "sample_annotation"):
        if instances[ann["instance_token"]] in walking:
            x, y, _ = ann["translation"]
            total += 1
            on_walkway += bool(devkit_maps[sample_location[ann["sample_token"]]].record_on_point(x, y, "walkway"))
    assert total and on_walkway / total > 0.6  # a few stand on the kerb of the parking row


def test_map_expansion_is_deterministic(tmp_path):
    a = synthesize(tmp_path / "a", scenes=2, samples_per_scene=3, seed=3, with_can_bus=False)
    b = synthesize(tmp_path / "b", scenes=2, samples_per_scene=3, seed=3, with_can_bus=False)
    files = sorted(p.name for p in (a / "maps" / "expansion").glob("*.json"))
    assert files
    for name in files:
        assert (a / "maps" / "expansion" / name).read_bytes() == (b / "maps" / "expansion" / name).read_bytes()


def test_the_drivable_area_holds_the_road_from_its_first_point():
    """The map holds the road it is drawn for from where the road begins (`Road.s_m[0]`): across the drivable
    band (-9 m .. 12 m of the centreline), the road's first 30 m lie in the drivable area, as shapely reads the
    JSON's polygons (a map starting a grid step late leaves the road's first half metre off the map)."""
    import shapely

    from nuparquet.synth.map_expansion import map_expansion
    from nuparquet.synth.road import make_road

    road, _ = make_road(np.random.default_rng(5), -100.0, 200.0, 50.0)
    data = map_expansion(5, 0, "boston-seaport", [road], drives_on_right=True)
    nodes = {n["token"]: (n["x"], n["y"]) for n in data["node"]}
    polygons = {p["token"]: shapely.Polygon([nodes[t] for t in p["exterior_node_tokens"]],
                                            [[nodes[t] for t in hole["node_tokens"]] for hole in p["holes"]])
                for p in data["polygon"]}
    drivable = shapely.union_all([polygons[t] for r in data["drivable_area"] for t in r["polygon_tokens"]])
    s = road.s_m[road.s_m <= road.s_m[0] + 30.0]
    assert s[0] == road.s_m[0] == -100.0 and len(s) == 61
    for lateral in (-8.9, 0.0, 11.9):
        xy, _ = road.at(s, lateral)
        inside = shapely.covers(drivable.buffer(1e-6), shapely.points(xy))
        assert inside.all(), (lateral, s[~inside])
