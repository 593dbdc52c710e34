"""Which map surface each annotation and ego pose lies on: the tokens are the devkit's `layers_on_point` for the
box centre, the surface follows the documented precedence; the stats sections appear when map/ was converted."""

from __future__ import annotations

import json

import polars as pl
import pytest
import shapely

import nuparquet
from nuparquet.queries.map import annotation_surfaces, ego_time_on_surfaces, surfaces_by_category
from nuparquet.queries.sections import default_sections

pytestmark = pytest.mark.devkit


def _surface(on: dict, connector: str, intersections: set[str]) -> str:
    for layer in ("ped_crossing", "walkway", "carpark_area"):
        if on[layer]:
            return layer
    if on["road_segment"] in intersections:
        return "intersection"
    if on["lane"] or connector:
        return "lane"
    return "drivable_area" if on["drivable_area"] else "off_map"


def _connector(nusc_map, x: float, y: float) -> str:
    """The first lane connector strictly containing the point (the devkit's record_on_point refuses the layer)."""
    point = shapely.Point(x, y)
    return next((r["token"] for r in nusc_map.lane_connector
                 if point.within(nusc_map.extract_polygon(r["polygon_token"]))), "")


def _intersections(devkit_maps) -> set[str]:
    return {r["token"] for m in devkit_maps.values() for r in m.road_segment if r["is_intersection"]}


def test_annotation_surfaces_match_the_devkit(map_out, devkit_maps):
    ds = nuparquet.open(map_out)
    rows = annotation_surfaces(ds).collect()
    assert rows.height == ds.scan("annotations").select(pl.len()).collect().item()
    intersections = _intersections(devkit_maps)
    for row in rows.gather_every(3).iter_rows(named=True):
        nusc_map = devkit_maps[row["location"]]
        on = nusc_map.layers_on_point(row["x_m"], row["y_m"])
        assert {k: row[k] for k in on} == on
        connector = _connector(nusc_map, row["x_m"], row["y_m"])
        assert row["lane_connector"] == connector
        assert row["surface"] == _surface(on, connector, intersections)
    walkers = rows.filter(pl.col("category_name") == "human.pedestrian.adult")
    assert (walkers["surface"] == "walkway").mean() > 0.6
    table = surfaces_by_category(ds).collect()
    assert table["total"].sum() == rows.height
    adults = table.filter(pl.col("category_name") == "human.pedestrian.adult").row(0, named=True)
    assert adults["walkway"] == (walkers["surface"] == "walkway").sum()


def test_ego_time_on_surfaces_match_the_devkit(map_root, map_out, devkit_maps):
    ds = nuparquet.open(map_out)
    shares = ego_time_on_surfaces(ds).collect()
    intersections = _intersections(devkit_maps)
    scenes = {r["name"]: r for r in json.loads((map_root / "v1.0-synth" / "scene.json").read_text())}
    logs = {r["token"]: r["location"] for r in json.loads((map_root / "v1.0-synth" / "log.json").read_text())}
    poses = ds.scan("frames").filter(pl.col("is_key_frame") & (pl.col("channel") == "LIDAR_TOP")).select(
        "scene_name", "ego_translation").collect()
    for row in shares.iter_rows(named=True):
        nusc_map = devkit_maps[logs[scenes[row["scene_name"]]["log_token"]]]
        xy = [(t[0], t[1]) for t in poses.filter(pl.col("scene_name") == row["scene_name"])["ego_translation"].to_list()]
        assert row["keyframes"] == len(xy)
        surfaces = [_surface(nusc_map.layers_on_point(x, y), _connector(nusc_map, x, y), intersections) for x, y in xy]
        assert row["share_intersection"] == pytest.approx(surfaces.count("intersection") / len(xy))
        assert row["share_lane"] == pytest.approx(surfaces.count("lane") / len(xy))
        assert row["share_off_map"] == 0.0


def test_map_sections_join_the_default_stats_when_map_was_converted(map_out, synth_out, tmp_path):
    assert {"map_surfaces", "ego_on_map"} <= set(default_sections(nuparquet.open(map_out)))
    from nuparquet.conversion import convert
    convert_out = tmp_path / "no-map"
    manifest = json.loads((synth_out / "manifest.json").read_text())
    convert(manifest["source"]["dataroot"], manifest["source"]["version"], convert_out, no_map=True)
    assert not {"map_surfaces", "ego_on_map"} & set(default_sections(nuparquet.open(convert_out)))


def test_no_annotations_give_empty_surface_tables_with_every_column(irregular_empty_out):
    """A split without annotations (the test set's shape): the surface queries answer empty tables with their
    columns, as with annotations, not an error."""
    from nuparquet.queries.map import LAYERS, SURFACES

    ds = nuparquet.open(irregular_empty_out)
    assert "map/lane" in ds.datasets and ds.scan("annotations").select(pl.len()).collect().item() == 0
    rows = annotation_surfaces(ds).collect()
    assert rows.height == 0
    assert rows.columns == ["token", "scene_name", "location", "category_name", "x_m", "y_m", *LAYERS, "surface"]
    assert rows.schema["surface"] == pl.String
    table = surfaces_by_category(ds).collect()
    assert table.height == 0 and table.columns == ["category_name", *SURFACES, "total"]
