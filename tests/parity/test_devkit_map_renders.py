"""The map explorer's figures (`nuparquet.devkit.map_expansion.map_renders`) against the devkit's, pixel for pixel
where the devkit's render works under shapely 2 (centrelines, masks, line layers, a basemap under them); where it
raises (descartes' IndexError on every polygon), ours draws and its polygons are the records' rings, and the whole
figure equals the devkit's own code run with descartes' patch built from the rings' coordinates. Then a subclass of
the explorer in MapTR's pattern (`CNuScenesMapExplorer(nusc_map)` overriding `_get_layer_line` /
`_get_layer_polygon`) on both."""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest
from shapely import affinity
from shapely.geometry import MultiPolygon

os.environ.setdefault("MPLBACKEND", "Agg")

import matplotlib.pyplot as plt  # noqa: E402
from nuscenes.map_expansion import map_api as devkit_map_api  # noqa: E402
from nuscenes.map_expansion.bitmap import BitMap as DevkitBitMap  # noqa: E402

from nuparquet.devkit.map_expansion.bitmap import BitMap  # noqa: E402
from nuparquet.devkit.map_expansion.map_api import NuScenesMap, NuScenesMapExplorer  # noqa: E402
from nuparquet.devkit.map_expansion.map_renders import polygon_patch  # noqa: E402

pytestmark = pytest.mark.devkit


@pytest.fixture(scope="module")
def pair(devkit_maps, map_out, map_root, tmp_path_factory):
    """boston-seaport's devkit map and ours, on a dataroot without the map JSON but with a basemap PNG."""
    root = tmp_path_factory.mktemp("map-renders") / "data"
    shutil.copytree(map_root / "maps", root / "maps", ignore=shutil.ignore_patterns("expansion"))
    (root / "maps" / "basemap").mkdir()
    from PIL import Image

    rng = np.random.default_rng(5)
    Image.fromarray(rng.integers(0, 255, (60, 90), dtype=np.uint8)).save(root / "maps" / "basemap" / "boston-seaport.png")
    return devkit_maps["boston-seaport"], NuScenesMap(str(root), "boston-seaport", parquet=map_out), root


def _pixels(fig) -> np.ndarray:
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba()).copy()
    plt.close(fig)
    return image


def _figure(result):
    return result[0] if not isinstance(result[0], np.ndarray) else result[1]


def test_the_renders_that_work_in_the_devkit_give_its_pixels(pair):
    theirs, ours, root = pair
    x, y, _ = theirs.arcline_path_3[theirs.lane[0]["token"]][0]["start_pose"]
    calls = [
        lambda m: m.render_centerlines(resolution_meters=2.0, figsize=(4.0, 3.0)),
        lambda m: m.render_layers(["lane_divider", "road_divider", "traffic_light"], 0.7, figsize=(4.0, 3.0)),
        lambda m: m.render_layers(["lane_divider"], 0.5, figsize=(4.0, 3.0), tokens=[theirs.lane_divider[1]["token"]]),
        lambda m: m.render_map_mask((x, y, 60.0, 40.0), 25.0, ["lane", "drivable_area", "walkway", "lane_divider"],
                                    canvas_size=(60, 40), figsize=(4, 4), n_row=2),
    ]
    for call in calls:
        expected, mine = _pixels(_figure(call(theirs))), _pixels(_figure(call(ours)))
        assert mine.shape == expected.shape and np.array_equal(mine, expected)
        assert len(np.unique(expected.reshape(-1, 4), axis=0)) > 2  # something is drawn
    bitmap, devkit_bitmap = BitMap(str(root), "boston-seaport", "basemap"), DevkitBitMap(str(root), "boston-seaport",
                                                                                         "basemap")
    assert np.array_equal(bitmap.image, devkit_bitmap.image)
    expected = _pixels(_figure(theirs.render_centerlines(2.0, figsize=(4.0, 3.0), bitmap=devkit_bitmap)))
    assert np.array_equal(_pixels(_figure(ours.render_centerlines(2.0, figsize=(4.0, 3.0), bitmap=bitmap))), expected)
    for layer in ("semantic_prior", "nope"):  # the generator's PNGs are not the devkit's semantic prior hashes
        for cls in (BitMap, DevkitBitMap):
            with pytest.raises(Exception, match="Cannot find|Invalid bitmap layer"):
                cls(str(root), "boston-seaport", layer)


def _descartes_for_shapely_2(monkeypatch):
    """The devkit's render code with descartes' PolygonPatch taking the rings' coordinates (what it meant)."""
    monkeypatch.setattr(devkit_map_api.descartes, "PolygonPatch", polygon_patch)


def test_the_polygon_renders_draw_where_the_devkits_raise(pair, monkeypatch):
    theirs, ours, _ = pair
    lane = theirs.lane[0]
    x, y = theirs.extract_polygon(lane["polygon_token"]).representative_point().coords[0]
    box = (x - 60, y - 40, x + 60, y + 40)
    calls = [
        lambda m: m.render_map_patch(box, figsize=(4, 4)),
        lambda m: m.render_layers(["lane", "walkway", "drivable_area"], 0.5, figsize=(4.0, 3.0)),
        lambda m: m.render_record("lane", lane["token"], figsize=(5.0, 4.0)),
        lambda m: m.render_next_roads(x, y, figsize=(4.0, 3.0)),
    ]
    for call in calls:
        with pytest.raises(IndexError):  # descartes' asarray(polygon.exterior)[:, :2] under shapely 2
            call(theirs)
        plt.close("all")
    figures = [call(ours) for call in calls]
    fig, ax = figures[0]
    patches = [p for p in ax.patches if type(p).__name__ == "PathPatch"]
    n_polygons = sum(len(r["polygon_tokens"]) for r in theirs.drivable_area) + sum(
        len(getattr(theirs, layer)) for layer in theirs.non_geometric_polygon_layers if layer != "drivable_area")
    assert len(patches) == n_polygons  # every polygon of every layer, the devkit's loop
    holed = next(p for p in theirs.polygon if any(h["node_tokens"] for h in p["holes"]))
    shape = theirs.extract_polygon(holed["token"])
    path = polygon_patch(shape).get_path()
    rings = [np.asarray(shape.exterior.coords)] + [np.asarray(r.coords) for r in shape.interiors]
    assert np.array_equal(path.vertices, np.concatenate(rings))  # the exterior then the hole, as descartes
    assert (path.codes == 1).sum() == len(rings)  # a MOVETO starts each ring
    mine = [_pixels(_figure(f)) for f in figures]
    _descartes_for_shapely_2(monkeypatch)
    for image, call in zip(mine, calls):
        assert np.array_equal(image, _pixels(_figure(call(theirs))))


def test_egoposes_on_the_fancy_map_from_our_nuscenes(pair, map_out, devkit, map_root, monkeypatch, tmp_path,
                                                      capsys):
    from conftest import SYNTH_VERSION

    from nuparquet.devkit import NuScenes

    theirs, ours, _ = pair
    nusc = devkit.NuScenes(SYNTH_VERSION, str(map_root), verbose=False)
    with pytest.raises(IndexError):
        theirs.render_egoposes_on_fancy_map(nusc, verbose=False)
    plt.close("all")
    out = tmp_path / "fancy.png"
    poses, fig, ax = ours.render_egoposes_on_fancy_map(NuScenes(SYNTH_VERSION, str(map_out), verbose=False),
                                                       verbose=False, out_path=str(out))
    assert out.stat().st_size > 0
    _descartes_for_shapely_2(monkeypatch)
    expected, devkit_fig, _ = theirs.render_egoposes_on_fancy_map(nusc, verbose=False)
    assert poses.dtype == expected.dtype and np.array_equal(poses, expected) and len(poses) > 0
    assert np.array_equal(_pixels(fig), _pixels(devkit_fig))
    plt.close("all")
    # verbose: the devkit's printout (its check of each scene against the bad-localisation list), the same poses
    theirs_verbose, _, _ = theirs.render_egoposes_on_fancy_map(nusc, verbose=True)
    printed_theirs = capsys.readouterr().out
    ours_verbose, _, _ = ours.render_egoposes_on_fancy_map(NuScenes(SYNTH_VERSION, str(map_out), verbose=False),
                                                           verbose=True)
    assert capsys.readouterr().out == printed_theirs and "Adding ego poses to map..." in printed_theirs
    assert np.array_equal(ours_verbose, expected) and np.array_equal(theirs_verbose, expected)
    plt.close("all")


def _maptr_explorer(base):
    """MapTR's `CNuScenesMapExplorer` (maptrv2's map ground truth), restated over either explorer class."""

    class CNuScenesMapExplorer(base):
        def __init__(self, *args, **kwargs):
            super(self.__class__, self).__init__(*args, **kwargs)

        def _get_layer_polygon(self, patch_box, patch_angle, layer_name, return_token=False):
            if layer_name not in self.map_api.non_geometric_polygon_layers:
                raise ValueError('{} is not a polygonal layer'.format(layer_name))
            patch_x, patch_y = patch_box[0], patch_box[1]
            patch = self.get_patch_coord(patch_box, patch_angle)
            records = getattr(self.map_api, layer_name)
            polygon_list = []
            if layer_name == 'drivable_area':
                for record in records:
                    polygons = [self.map_api.extract_polygon(t) for t in record['polygon_tokens']]
                    for polygon in polygons:
                        new_polygon = polygon.intersection(patch)
                        if not new_polygon.is_empty:
                            new_polygon = affinity.rotate(new_polygon, -patch_angle, origin=(patch_x, patch_y),
                                                          use_radians=False)
                            new_polygon = affinity.affine_transform(new_polygon, [1.0, 0.0, 0.0, 1.0, -patch_x, -patch_y])
                            if new_polygon.geom_type == 'Polygon':
                                new_polygon = MultiPolygon([new_polygon])
                            polygon_list.append((record['token'], new_polygon) if return_token else new_polygon)
            else:
                for record in records:
                    polygon = self.map_api.extract_polygon(record['polygon_token'])
                    if polygon.is_valid:
                        new_polygon = polygon.intersection(patch)
                        if not new_polygon.is_empty:
                            new_polygon = affinity.rotate(new_polygon, -patch_angle, origin=(patch_x, patch_y),
                                                          use_radians=False)
                            new_polygon = affinity.affine_transform(new_polygon, [1.0, 0.0, 0.0, 1.0, -patch_x, -patch_y])
                            if new_polygon.geom_type == 'Polygon':
                                new_polygon = MultiPolygon([new_polygon])
                            polygon_list.append((record['token'], new_polygon) if return_token else new_polygon)
            return polygon_list

        def _get_layer_line(self, patch_box, patch_angle, layer_name, return_token=False):
            if layer_name not in self.map_api.non_geometric_line_layers:
                raise ValueError("{} is not a line layer".format(layer_name))
            if layer_name == 'traffic_light':
                return None
            patch_x, patch_y = patch_box[0], patch_box[1]
            patch = self.get_patch_coord(patch_box, patch_angle)
            line_list = []
            for record in getattr(self.map_api, layer_name):
                line = self.map_api.extract_line(record['line_token'])
                if line.is_empty:
                    continue
                new_line = line.intersection(patch)
                if not new_line.is_empty:
                    new_line = affinity.rotate(new_line, -patch_angle, origin=(patch_x, patch_y), use_radians=False)
                    new_line = affinity.affine_transform(new_line, [1.0, 0.0, 0.0, 1.0, -patch_x, -patch_y])
                    line_list.append((record['token'], new_line) if return_token else new_line)
            return line_list

    return CNuScenesMapExplorer


def test_a_subclass_in_maptrs_pattern_gives_the_devkits_answers(pair):
    theirs, ours, _ = pair
    mine = _maptr_explorer(NuScenesMapExplorer)(ours)
    expected = _maptr_explorer(devkit_map_api.NuScenesMapExplorer)(theirs)
    assert mine.map_api is ours and mine.canvas_max_x == expected.canvas_max_x
    rng = np.random.default_rng(8)
    xy = np.array([[n["x"], n["y"]] for n in theirs.node])
    drawn = 0
    for cx, cy in xy[rng.integers(0, len(xy), 6)]:
        patch_box, angle = (cx, cy, 60.0, 30.0), float(rng.uniform(-180, 180))
        for layer in ("ped_crossing", "drivable_area", "lane"):
            a = mine._get_layer_polygon(patch_box, angle, layer, return_token=True)
            b = expected._get_layer_polygon(patch_box, angle, layer, return_token=True)
            assert [t for t, _ in a] == [t for t, _ in b] and all(p.equals_exact(q, 0.0) for (_, p), (_, q) in zip(a, b))
        for layer in ("road_divider", "lane_divider"):
            a = mine._get_layer_line(patch_box, angle, layer, return_token=True)
            b = expected._get_layer_line(patch_box, angle, layer, return_token=True)
            assert [t for t, _ in a] == [t for t, _ in b] and all(p.equals_exact(q, 0.0) for (_, p), (_, q) in zip(a, b))
        layers = ["drivable_area", "lane", "ped_crossing", "walkway"]  # the override runs inside get_map_mask
        mask = mine.get_map_mask(patch_box, angle, layers, (60, 30))
        assert np.array_equal(mask, expected.get_map_mask(patch_box, angle, layers, (60, 30)))
        assert np.array_equal(mask, ours.get_map_mask(patch_box, angle, layers, (60, 30)))
        drawn += int(mask.sum() > 0)
    assert drawn >= 3


def test_map_in_image_from_our_nuscenes_equals_the_devkits_code(synth_root, synth_out, devkit, monkeypatch, tmp_path):
    """`render_map_in_image` on a camera image (the synthetic set with images): the devkit's raises in descartes;
    ours, fed our NuScenes, draws the devkit's figure pixel for pixel (the devkit's code with the shapely 2 patch)."""
    from conftest import SYNTH_VERSION

    from nuparquet.devkit import NuScenes

    nusc = devkit.NuScenes(SYNTH_VERSION, str(synth_root), verbose=False)
    sample = nusc.sample[len(nusc.sample) // 2]
    location = nusc.get("log", nusc.get("scene", sample["scene_token"])["log_token"])["location"]
    theirs = devkit_map_api.NuScenesMap(str(synth_root), location)
    ours = NuScenesMap(str(synth_out), location)
    with pytest.raises(IndexError):
        theirs.render_map_in_image(nusc, sample["token"], verbose=False)
    plt.close("all")
    out = tmp_path / "in-image.png"
    fig, ax = ours.render_map_in_image(NuScenes(SYNTH_VERSION, str(synth_out), verbose=False), sample["token"],
                                       verbose=False, out_path=str(out))
    assert out.stat().st_size > 0 and len(ax.patches) > 0  # map polygons drawn over the image
    mine = _pixels(fig)
    _descartes_for_shapely_2(monkeypatch)
    assert np.array_equal(mine, _pixels(theirs.render_map_in_image(nusc, sample["token"], verbose=False)[0]))
    with pytest.raises(AssertionError, match="Can only render non-geometry polygons"):
        ours.render_map_in_image(nusc, sample["token"], layer_names=["lane_divider"], verbose=False)


def test_a_subclass_overriding_is_record_in_patch_is_asked_for_every_record(pair):
    """A client's `is_record_in_patch` override is what `get_records_in_patch` asks, record by record with the box
    and the mode, as in the devkit (here it keeps only records the devkit's own test keeps and whose token ends in
    an even hex digit)."""
    theirs, ours, _ = pair

    def subclass(base):
        class Even(base):
            def is_record_in_patch(self, layer_name, token, box_coords, mode="intersect"):
                return super().is_record_in_patch(layer_name, token, box_coords, mode) and int(token[-1], 16) % 2 == 0
        return Even

    mine, expected = subclass(NuScenesMapExplorer)(ours), subclass(devkit_map_api.NuScenesMapExplorer)(theirs)
    node = theirs.node[len(theirs.node) // 2]
    box = (node["x"] - 80, node["y"] - 80, node["x"] + 80, node["y"] + 80)
    layers = ["lane", "road_segment", "ped_crossing", "stop_line", "lane_divider"]
    for mode in ("intersect", "within"):
        got = mine.get_records_in_patch(box, layers, mode)
        assert got == expected.get_records_in_patch(box, layers, mode), mode
        assert any(got.values()) and all(int(t[-1], 16) % 2 == 0 for tokens in got.values() for t in tokens)


def test_a_patch_of_no_polygon_is_refused_as_descartes_refuses_it():
    import descartes
    import shapely

    from nuparquet.devkit.map_expansion.map_renders import polygon_patch

    for geometry in (shapely.Point(0, 0), shapely.LineString([(0, 0), (1, 1)])):
        with pytest.raises(ValueError) as theirs:
            descartes.PolygonPatch(geometry)
        with pytest.raises(ValueError) as ours:
            polygon_patch(geometry)
        assert str(ours.value) == str(theirs.value) == "A polygon or multi-polygon representation is required"
