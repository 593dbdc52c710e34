"""map/ datasets from the map expansion: one row per record of every layer, geometry equal to the devkit's
`extract_polygon` / `extract_line` coordinate for coordinate, lane centrelines equal to `discretize_lanes`,
GeoParquet that geopandas reads, every map file written back exactly, and bad map files as clean problems."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest
import shapely
from shapely.geometry import MultiPolygon

from conftest import SYNTH_VERSION, first_map
from nuparquet.cli.main import main
from nuparquet.conversion import convert
from nuparquet.export.json_files import export_json

POLYGON_LAYERS = ["drivable_area", "road_segment", "road_block", "lane", "ped_crossing", "walkway", "stop_line",
                  "carpark_area", "lane_connector"]
LINE_LAYERS = ["road_divider", "lane_divider", "traffic_light"]


def _layer(map_out, layer):
    return pq.read_table(map_out / "map" / layer).to_pylist()


def test_every_layer_has_the_devkits_records_in_file_order(map_out, devkit_maps):
    for layer in ["node", "line", "polygon"] + POLYGON_LAYERS + LINE_LAYERS:
        rows = _layer(map_out, layer)
        for location, nusc_map in devkit_maps.items():
            mine = [r["token"] for r in rows if r["location"] == location]
            assert mine == [r["token"] for r in getattr(nusc_map, layer)], (layer, location)
    manifest = json.loads((map_out / "manifest.json").read_text())
    assert {f"map/{layer}" for layer in POLYGON_LAYERS + LINE_LAYERS + ["node", "line", "polygon", "lane_centerlines",
                                                                          "connectivity", "arcline_path_3"]} <= set(manifest["datasets"])
    assert sorted(f["path"] for f in manifest["files"] if f["kind"] == "map_expansion") == \
        sorted(f"maps/expansion/{loc}.json" for loc in devkit_maps)


def _same_coordinates(a, b) -> bool:
    """Same type, same rings/parts, bit-identical coordinates (shapely's equals_exact with tolerance 0)."""
    return a.geom_type == b.geom_type and shapely.equals_exact(a, b, tolerance=0.0)


def test_geometry_is_the_devkits_coordinate_for_coordinate(map_out, devkit_maps):
    checked = 0
    for layer in POLYGON_LAYERS + LINE_LAYERS:
        for row in _layer(map_out, layer):
            nusc_map = devkit_maps[row["location"]]
            mine = shapely.from_wkb(row["geometry"])
            if layer == "drivable_area":
                expected = MultiPolygon([nusc_map.extract_polygon(t) for t in row["polygon_tokens"]])
            elif layer in POLYGON_LAYERS:
                expected = nusc_map.extract_polygon(row["polygon_token"])
            else:
                expected = nusc_map.extract_line(row["line_token"])
            assert _same_coordinates(mine, expected), (layer, row["token"])
            box = row["bbox"]
            assert (box["xmin"], box["ymin"], box["xmax"], box["ymax"]) == expected.bounds
            if layer != "lane_connector":  # the devkit has no bounds for connectors
                assert expected.bounds == tuple(nusc_map.get_bounds(layer, row["token"]))
            checked += 1
    holes = [r for r in _layer(map_out, "polygon") if r["holes"]]
    assert holes and all(len(shapely.from_wkb(r["geometry"]).interiors) == len(r["holes"]) for r in holes)
    assert checked > 300


def test_lane_centerlines_are_the_devkits_discretisation(map_out, devkit_maps):
    rows = _layer(map_out, "lane_centerlines")
    for location, nusc_map in devkit_maps.items():
        mine = [r for r in rows if r["location"] == location]
        tokens = [r["token"] for r in nusc_map.lane + nusc_map.lane_connector]
        assert [r["token"] for r in mine] == tokens
        expected = nusc_map.discretize_lanes(tokens, 0.5)
        for row in mine:
            poses = np.array(expected[row["token"]])
            assert np.array_equal(np.c_[row["x_m"], row["y_m"], row["yaw_rad"]], poses), row["token"]
            assert np.array_equal(np.asarray(shapely.from_wkb(row["geometry"]).coords), poses[:, :2])
    connectivity = _layer(map_out, "connectivity")
    for location, nusc_map in devkit_maps.items():
        for row in (r for r in connectivity if r["location"] == location):
            assert row["outgoing"] == nusc_map.get_outgoing_lane_ids(row["lane_token"])
            assert row["incoming"] == nusc_map.get_incoming_lane_ids(row["lane_token"])


def test_geoparquet_files_read_by_geopandas_with_types_and_bounds(map_out, devkit_maps):
    import geopandas  # the test extra: an independent GeoParquet reader
    expected_type = {"drivable_area": "MultiPolygon", "lane": "Polygon", "walkway": "Polygon", "lane_divider": "LineString",
                     "node": "Point", "lane_centerlines": "LineString"}
    for layer, geom_type in expected_type.items():
        path = next((map_out / "map" / layer).glob("*.parquet"))
        frame = geopandas.read_parquet(path)
        assert set(frame.geometry.geom_type) == {geom_type}
        assert frame.crs is None
        geo = json.loads(pq.read_schema(path).metadata[b"geo"])
        assert geo["version"] == "1.1.0" and geo["primary_column"] == "geometry"
        column = geo["columns"]["geometry"]
        assert column["encoding"] == "WKB" and column["geometry_types"] == [geom_type] and column["crs"] is None
        assert column["covering"]["bbox"]["xmin"] == ["bbox", "xmin"]
        assert column["bbox"] == pytest.approx(list(frame.total_bounds), abs=0)
    # every map layer (the centerlines too) says where its coordinates come from: each map's canvas and version
    # as its JSON holds them; the centerlines their resolution (the devkit's get_closest_lane: 0.5 m)
    for layer, resolution in (("node", None), ("lane", None), ("lane_centerlines", 0.5)):
        path = next((map_out / "map" / layer).glob("*.parquet"))
        facts = json.loads(pq.read_schema(path).metadata[b"nuparquet.map"])
        assert facts.get("resolution_m") == resolution and set(facts["maps"]) == set(devkit_maps), layer
        for location, nusc_map in devkit_maps.items():
            assert facts["maps"][location]["canvas_edge_m"] == list(nusc_map.canvas_edge), (layer, location)
            assert facts["maps"][location]["version"] == nusc_map.version, (layer, location)
    lanes = geopandas.read_parquet(next((map_out / "map" / "lane").glob("*.parquet")))
    for location, nusc_map in devkit_maps.items():
        ours = lanes[lanes.location == location].total_bounds
        xy = np.array([nusc_map.extract_polygon(r["polygon_token"]).bounds for r in nusc_map.lane])
        assert list(ours) == [xy[:, 0].min(), xy[:, 1].min(), xy[:, 2].max(), xy[:, 3].max()]


def test_geo_metadata_names_each_geometry_type_as_geoparquet_does():
    """`with_geo_metadata` on one geometry of each kind (a null beside it): GeoParquet's `geometry_types` are the
    OGC names, which are shapely's `geom_type`, and its bbox is the geometry's bounds; the same when the metadata
    parses the geometries back from the WKB column. Today's layers hold Point, LineString, Polygon and MultiPolygon
    only (the test above); a map of other types must still get the names readers look for."""
    import pyarrow as pa

    from nuparquet.map.geo import geometry_columns, with_geo_metadata

    kinds = [shapely.Point(1.0, 2.0), shapely.LineString([(0.0, 0.0), (3.0, 4.0)]), shapely.box(1.0, 1.0, 2.0, 3.0),
             shapely.MultiPoint([(0.0, 1.0), (5.0, -2.0)]),
             shapely.MultiLineString([[(0.0, 0.0), (1.0, 1.0)], [(2.0, 2.0), (4.0, -1.0)]]),
             shapely.MultiPolygon([shapely.box(0.0, 0.0, 1.0, 1.0), shapely.box(3.0, 3.0, 5.0, 6.0)])]
    for geometry in kinds:
        geometries = np.array([geometry, None], dtype=object)
        wkb, bbox = geometry_columns(geometries)
        table = pa.table({"geometry": wkb, "bbox": bbox})
        for given in (geometries, None):
            column = json.loads(with_geo_metadata(table, None, given).schema.metadata[b"geo"])["columns"]["geometry"]
            assert column["geometry_types"] == [geometry.geom_type], geometry.wkt
            assert column["bbox"] == list(geometry.bounds), geometry.wkt
    mixed = np.array(kinds, dtype=object)
    table = pa.table(dict(zip(("geometry", "bbox"), geometry_columns(mixed))))
    column = json.loads(with_geo_metadata(table, None, mixed).schema.metadata[b"geo"])["columns"]["geometry"]
    assert sorted(column["geometry_types"]) == sorted(g.geom_type for g in kinds)  # each once, in no set order


def test_export_json_writes_every_map_file_back_exactly(map_root, map_out, tmp_path):
    export_json(map_out, tmp_path / "back")
    files = sorted((map_root / "maps" / "expansion").glob("*.json"))
    assert files
    for original in files:
        again = tmp_path / "back" / "maps" / "expansion" / original.name
        a, b = json.loads(original.read_text()), json.loads(again.read_text())
        assert a == b
        assert json.dumps(a) == json.dumps(b)  # key order everywhere, ints stay ints (1 vs 1.0)


def test_unusual_values_come_back_exactly(small_map_root, tmp_path):
    path = first_map(small_map_root)
    data = json.loads(path.read_text())
    data["node"][3]["x"] = 512  # an integer coordinate among floats
    data["lane"][0] = dict(reversed(list(data["lane"][0].items())))  # another key order
    data["traffic_light"][0]["items"][0]["rel_pos"]["tx"] = 0  # an int inside a nested struct: kept as JSON text
    data["extra_top_level"] = {"note": [1, 2.5]}
    nodes = [n["token"] for n in data["node"][:2]]
    data["polygon"].append({"token": "degenerate", "exterior_node_tokens": nodes, "holes": []})  # no polygon: null
    path.write_text(json.dumps(data))
    convert(small_map_root, SYNTH_VERSION, tmp_path / "out")
    degenerate = [r for r in _layer(tmp_path / "out", "polygon") if r["token"] == "degenerate"]
    assert degenerate[0]["geometry"] is None and degenerate[0]["bbox"] is None
    export_json(tmp_path / "out", tmp_path / "back")
    again = json.loads((tmp_path / "back" / "maps" / "expansion" / path.name).read_text())
    assert json.dumps(again) == json.dumps(data)


def test_a_map_without_connectivity_has_an_empty_connectivity_dataset_of_lane_token_lists(small_map_root, tmp_path):
    """A map file whose connectivity is {} (no lane listed): map/connectivity has no row, and its `incoming` and
    `outgoing` are still lists of lane tokens (list<string>, as a map with lanes types them), so a reader's query on
    them works on this dataset as on any other; the file comes back exactly."""
    import pyarrow as pa

    path = first_map(small_map_root)
    data = json.loads(path.read_text())
    assert data["connectivity"]  # the generator's map lists lanes: the change below empties a real layer
    data["connectivity"] = {}
    path.write_text(json.dumps(data))
    convert(small_map_root, SYNTH_VERSION, tmp_path / "out")
    table = pq.read_table(tmp_path / "out" / "map" / "connectivity")
    assert table.num_rows == 0
    assert table.schema.field("incoming").type == table.schema.field("outgoing").type == pa.list_(pa.string())
    export_json(tmp_path / "out", tmp_path / "back")
    again = json.loads((tmp_path / "back" / "maps" / "expansion" / path.name).read_text())
    assert json.dumps(again) == json.dumps(data)


@pytest.mark.parametrize("change, expected", [
    (lambda d: d.update(version="1.2"), "map version '1.2' is older than 1.3"),
    (lambda d: d.pop("version"), "map version '1.0' is older than 1.3"),
    (lambda d: d["polygon"][5]["exterior_node_tokens"].__setitem__(1, "f" * 32),
     "names node '" + "f" * 32 + "' (exterior_node_tokens), which is not in the map's node list"),
    (lambda d: d["lane"][2].__setitem__("polygon_token", "nope"), "lane field polygon_token names polygon 'nope'"),
    (lambda d: d.pop("lane_connector"), "lacks the layer(s) lane_connector"),
])
def test_bad_map_files_are_problems_naming_file_and_token(small_map_root, tmp_path, capsys, change, expected):
    path = first_map(small_map_root)
    data = json.loads(path.read_text())
    token = data["polygon"][5]["token"] if "exterior" in expected else data["lane"][2]["token"] if "nope" in expected else None
    change(data)
    path.write_text(json.dumps(data))
    out = tmp_path / "out"
    assert main(["convert", str(small_map_root), "--version", SYNTH_VERSION, "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert f"maps/expansion/{path.name}" in err and expected in err, err
    if token:
        assert f"token={token}" in err
    assert not out.exists()


def test_problems_in_two_map_files_are_all_reported(small_map_root, tmp_path, capsys):
    first = first_map(small_map_root)
    second = first.with_name("singapore-onenorth.json" if first.stem != "singapore-onenorth" else "boston-seaport.json")
    shutil.copy(first, second)  # a second map file, read after or before the first
    paths = sorted([first, second])
    for path, version in zip(paths, ("1.1", "1.2")):
        data = json.loads(path.read_text())
        data["version"] = version
        path.write_text(json.dumps(data))
    assert main(["convert", str(small_map_root), "--version", SYNTH_VERSION, "--out", str(tmp_path / "out"), "--quiet"]) == 1
    err = capsys.readouterr().err
    for path, version in zip(paths, ("1.1", "1.2")):
        assert f"maps/expansion/{path.name}" in err and f"map version '{version}' is older than 1.3" in err, err


def test_truncated_map_file_is_a_problem(small_map_root, tmp_path, capsys):
    path = first_map(small_map_root)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    assert main(["convert", str(small_map_root), "--version", SYNTH_VERSION, "--out", str(tmp_path / "out"), "--quiet"]) == 1
    assert f"maps/expansion/{path.name}: not valid JSON" in capsys.readouterr().err


def test_no_map_flag_and_missing_folder_skip_with_a_reason(small_map_root, tmp_path):
    manifest = convert(small_map_root, SYNTH_VERSION, tmp_path / "a", no_map=True)
    assert manifest["skipped"]["map"] == "not requested (--no-map)"
    assert not (tmp_path / "a" / "map").exists()
    shutil.rmtree(small_map_root / "maps" / "expansion")
    manifest = convert(small_map_root, SYNTH_VERSION, tmp_path / "b")
    assert manifest["skipped"]["map"] == "no maps/expansion/ folder in the dataroot"
    assert not any(name.startswith("map/") for name in manifest["datasets"])
