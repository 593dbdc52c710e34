"""The bird's-eye view: `render --channel bev` writes an H.264 video with one frame per reference-lidar
keyframe, its pixels show the map where the devkit's map says each layer is (north-up and ego-up), boxes and
the ego are drawn, and `--bev` adds the view as a tile beside the cameras of `--channel all`."""

from __future__ import annotations

import av
import cv2
import numpy as np
import polars as pl
import pytest
import shapely

import nuparquet
from nuparquet.cli.main import main

# Independent statement of the documented draw order and colours (nuparquet.rendering.bev.MAP_STYLE), top layer last.
FILLS = [("drivable_area", (78, 78, 78)), ("carpark_area", (60, 90, 120)), ("walkway", (70, 115, 70)),
         ("lane", (98, 98, 98)), ("ped_crossing", (165, 165, 165)), ("stop_line", (50, 50, 200))]
BACKGROUND = (32, 32, 32)
SCENE = "scene-0001"


def _probe(path):
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames = sum(1 for _ in container.decode(stream))
        return stream.codec_context.name, stream.codec_context.pix_fmt, frames


def _lidar_keyframes(out, scene):
    return (nuparquet.open(out).scan("frames")
            .filter((pl.col("scene_name") == scene) & pl.col("is_key_frame") & (pl.col("channel").cast(pl.String) == "LIDAR_TOP"))
            .sort("timestamp").select("ego_translation", "ego_rotation").collect())


def _yaw(q):
    w, x, y, z = q
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _expected(nusc_map, x, y):
    """(BGR of the top polygon layer at the point, distance to the nearest drawn edge, m)."""
    patch = (x - 3, y - 3, x + 3, y + 3)
    records = nusc_map.get_records_in_patch(patch, [l for l, _ in FILLS] + ["road_divider", "lane_divider"])
    color, point, edge_m = BACKGROUND, shapely.Point(x, y), np.inf
    for layer, bgr in FILLS:
        for token in records[layer]:
            record = nusc_map.get(layer, token)
            polygons = [nusc_map.extract_polygon(t) for t in record["polygon_tokens"]] if layer == "drivable_area" \
                else [nusc_map.extract_polygon(record["polygon_token"])]
            for polygon in polygons:
                edge_m = min(edge_m, polygon.boundary.distance(point))
                if polygon.contains(point):
                    color = bgr
    for layer in ("road_divider", "lane_divider"):
        for token in records[layer]:
            edge_m = min(edge_m, nusc_map.extract_line(nusc_map.get(layer, token)["line_token"]).distance(point))
    return color, edge_m


def _boxes_near(out, scene, k):
    annotations = nuparquet.open(out).scan("annotations").filter(pl.col("scene_name") == scene).collect()
    samples = annotations.select("sample_token", "timestamp").unique().sort("timestamp")["sample_token"]
    rows = annotations.filter(pl.col("sample_token") == samples[k])
    return np.array([t[:2] for t in rows["translation"].to_list()]), np.array([max(s[:2]) for s in rows["size"].to_list()])


@pytest.fixture(scope="module")
def bev_north(map_out, tmp_path_factory):
    folder = tmp_path_factory.mktemp("bev")
    assert main(["render", str(map_out), "--scene", SCENE, "--channel", "bev", "--bev-up", "north",
                 "--out", str(folder / "bev.mp4"), "--frames-dir", str(folder / "frames"), "--frame-format", "png",
                 "--quiet"]) == 0
    return folder


def test_bev_video_decodes_with_one_frame_per_keyframe(bev_north, map_out):
    codec, pix_fmt, frames = _probe(bev_north / "bev.mp4")
    assert (codec, pix_fmt) == ("h264", "yuv420p")
    assert frames == _lidar_keyframes(map_out, SCENE).height == len(list((bev_north / "frames").glob("*.png")))


@pytest.mark.parametrize("up", ["north", "ego"])
def test_bev_pixels_show_the_map_where_the_devkit_says(bev_north, map_out, devkit_maps, tmp_path, up):
    folder = bev_north
    if up == "ego":
        folder = tmp_path
        assert main(["render", str(map_out), "--scene", SCENE, "--channel", "bev", "--frames-dir", str(tmp_path / "frames"),
                     "--frame-format", "png", "--quiet", "--bev-range-m", "30", "--bev-size", "400"]) == 0
    location = nuparquet.open(map_out).scan("scenes").filter(pl.col("name") == SCENE).collect()["log_location"][0]
    nusc_map = devkit_maps[location]
    poses = _lidar_keyframes(map_out, SCENE)
    rng = np.random.default_rng(0)
    checked = {}
    for k in (0, poses.height - 1):
        image = cv2.imread(str(folder / "frames" / f"{k:05d}.png"))
        h, w = image.shape[:2]
        s = h / (2 * (50.0 if up == "north" else 30.0))  # pixels per metre
        ex, ey = poses["ego_translation"][k][:2]
        yaw = _yaw(poses["ego_rotation"][k]) if up == "ego" else np.pi / 2  # the direction shown as "up"
        centres, sizes = _boxes_near(map_out, SCENE, k)
        for u, v in rng.integers([0, 0], [w, h], (250, 2)):
            if u < 0.3 * w and v < 0.35 * h:  # the legend
                continue
            right, forward = (u - (w - 1) / 2) / s, ((h - 1) / 2 - v) / s
            x = ex + forward * np.cos(yaw) + right * np.sin(yaw)
            y = ey + forward * np.sin(yaw) - right * np.cos(yaw)
            if np.hypot(x - ex, y - ey) < 3.5 or (len(centres) and (np.hypot(*(centres - [x, y]).T) < sizes / 2 + 1.0).any()):
                continue  # the ego, a box
            color, edge_m = _expected(nusc_map, x, y)
            if edge_m < 2.0 / s + 0.3:
                continue  # an edge or a divider line
            pixel = tuple(int(c) for c in image[v, u])
            if pixel in [tuple(c) for _, c in FILLS] + [BACKGROUND]:  # else a lidar point (none here) or a label
                assert pixel == color, (k, u, v, x, y)
                checked[color] = checked.get(color, 0) + 1
    assert checked.get((78, 78, 78), 0) + checked.get((98, 98, 98), 0) > 30  # road under the ego's path
    assert checked.get((70, 115, 70), 0) > 5  # walkways beside it


def test_bev_tile_beside_the_cameras(synth_out, tmp_path):
    assert main(["render", str(synth_out), "--scene", SCENE, "--channel", "all", "--bev", "--scale", "0.25",
                 "--out", str(tmp_path / "all.mp4"), "--frames-dir", str(tmp_path / "f"), "--frame-format", "png",
                 "--quiet"]) == 0
    image = cv2.imread(str(next((tmp_path / "f").glob("*.png"))))
    tile_h = image.shape[0] // 2
    tile_w = image.shape[1] // 4
    assert image.shape[1] == 4 * tile_w  # the front row holds three cameras and the view
    bev = image[:tile_h, 3 * tile_w:]
    white = np.all(bev == 255, axis=2)  # the ego, at the tile's centre
    assert white[tile_h // 2 - 4:tile_h // 2 + 4, tile_w // 2 - 4:tile_w // 2 + 4].any()
    assert (bev == (70, 115, 70)).all(axis=2).sum() > 50  # walkway pixels: the map is drawn
    codec, pix_fmt, frames = _probe(tmp_path / "all.mp4")
    assert (codec, pix_fmt) == ("h264", "yuv420p") and frames == len(list((tmp_path / "f").glob("*.png")))


def test_bev_option_errors(map_out, tmp_path, capsys):
    assert main(["render", str(map_out), "--scene", SCENE, "--channel", "CAM_FRONT", "--bev", "--out",
                 str(tmp_path / "a.mp4"), "--quiet"]) == 2
    assert "--bev adds the bird's-eye view beside the cameras" in capsys.readouterr().err
    assert main(["render", str(map_out), "--scene", "scene-9999", "--channel", "bev", "--out",
                 str(tmp_path / "a.mp4"), "--quiet"]) == 2
    assert "unknown scene 'scene-9999'" in capsys.readouterr().err


def _legend_swatch_pixels(image):
    """Pixels of the legend's swatch column (left of its text, above the point colouring's line) holding a map
    layer's colour (the map under the panel is darkened to 35 %, so only swatches keep these colours there)."""
    swatches = [c for _, c in FILLS] + [(0, 200, 235), (215, 215, 215)]
    panel = image[:image.shape[0] // 2, 8:20]
    return sum(int((panel == c).all(axis=2).sum()) for c in swatches)


def test_the_legend_lists_map_layers_only_when_the_map_is_drawn(map_root, map_out, tmp_path):
    """Issue 24: the legend listed the map layers of a dataset converted without its map."""
    no_map = tmp_path / "no-map"
    nuparquet.convert(map_root, "v1.0-synth", no_map, no_map=True)
    assert not any(d.startswith("map/") for d in nuparquet.open(no_map).datasets)
    for out, name in ((map_out, "with"), (no_map, "without")):
        assert main(["render", str(out), "--scene", SCENE, "--channel", "bev", "--frames-dir", str(tmp_path / name),
                     "--frame-format", "png", "--bev-size", "400", "--quiet"]) == 0
    with_map = cv2.imread(str(tmp_path / "with" / "00000.png"))
    without_map = cv2.imread(str(tmp_path / "without" / "00000.png"))
    assert _legend_swatch_pixels(with_map) > 100  # eight layer swatches
    # Without the map, and without points (this set has no lidar files), the legend has nothing to say: no panel
    # (the background darkened to 35 %: 11 from 32) at all. Issue 38: it showed the point colour bar there.
    panel_rows = int((without_map[:, 7] == (11, 11, 11)).all(axis=1).sum())
    assert panel_rows == 0
    assert (without_map[:60, :60] == (32, 32, 32)).all()


@pytest.mark.parametrize("height", [400, 900, 1800])
@pytest.mark.parametrize("map_layers, points", [(True, "height"), (False, "height"), (False, "intensity")])
def test_everything_the_legend_draws_lies_on_its_darkened_panel(height, map_layers, points):
    """On a plain grey view, the legend darkens one panel in the top-left corner (to 35 %) and draws its swatches
    and text inside it, none on the undarkened view around it (the descenders of its last line included; the
    panel's extent read from its left edge and top row, where nothing is drawn)."""
    from nuparquet.rendering.bev import draw_legend

    grey = 120
    image = np.full((height, height, 3), grey, np.uint8)
    draw_legend(image, points=points, map_layers=map_layers)
    dark = int(grey * 0.35)
    rows = np.flatnonzero((image[:, 6] == dark).all(axis=1))  # the panel's first column
    columns = np.flatnonzero((image[rows[0]] == dark).all(axis=1))  # its first row: darkened, nothing drawn
    assert rows[0] == 6 and columns[0] == 6
    assert np.array_equal(rows, np.arange(rows[0], rows[-1] + 1))
    assert np.array_equal(columns, np.arange(columns[0], columns[-1] + 1))
    inside = np.zeros(image.shape[:2], bool)
    inside[rows[0]:rows[-1] + 1, columns[0]:columns[-1] + 1] = True
    assert not (image != grey).any(axis=2)[~inside].any()  # nothing drawn outside the panel


def test_footprints_are_the_devkits_bottom_corners_front_first_then_the_front_centre():
    """A box's footprint: its four bottom corners as the devkit's `Box.bottom_corners()` (front-left, front-right,
    rear-right, rear-left; length along the heading, width across it), then the centre of its front edge."""
    from nuscenes.utils.data_classes import Box
    from pyquaternion import Quaternion

    from nuparquet.rendering.bev import footprints

    centre, wlh = np.array([[10.0, 20.0, 1.0], [-3.0, 5.0, 0.5]]), np.array([[2.0, 4.0, 1.5], [1.0, 6.0, 2.0]])
    heading = np.array([0.0, 0.7])
    corners = footprints(centre, wlh, heading)
    assert corners.shape == (2, 5, 2)
    assert np.allclose(corners[0], [[12, 21], [12, 19], [8, 19], [8, 21], [12, 20]])  # by hand: l = 4 along x
    for b in range(2):
        box = Box(centre[b], wlh[b], Quaternion(axis=[0, 0, 1], angle=heading[b]))
        bottom = box.bottom_corners()[:2].T  # the devkit's order: front-right, front-left, rear-left, rear-right
        assert np.allclose(corners[b, :4], bottom[[1, 0, 3, 2]])
        assert np.allclose(corners[b, 4], centre[b, :2] + wlh[b, 1] / 2 * np.array([np.cos(heading[b]), np.sin(heading[b])]))


def test_each_keyframes_boxes_are_drawn_in_their_category_colour_around_their_centre(bev_north, map_out):
    """The boxes drawn on a view are the boxes of its own lidar frame: at each keyframe, pixels of every box's
    category colour (`palette.category_rgb`) lie within the box's reach of its centre."""
    from nuparquet.rendering.palette import category_rgb

    poses = _lidar_keyframes(map_out, SCENE)
    annotations = nuparquet.open(map_out).scan("annotations").filter(pl.col("scene_name") == SCENE).collect()
    samples = annotations.select("sample_token", "timestamp").unique().sort("timestamp")["sample_token"]
    seen = total = 0
    for k in range(poses.height):
        image = cv2.imread(str(bev_north / "frames" / f"{k:05d}.png")).astype(np.int64)
        h, w = image.shape[:2]
        s = h / (2 * 50.0)
        ex, ey = poses["ego_translation"][k][:2]
        rows = annotations.filter(pl.col("sample_token") == samples[k])
        for (x, y, _), size, name in zip(rows["translation"], rows["size"], rows["category_name"]):
            u, v = (w - 1) / 2 + (x - ex) * s, (h - 1) / 2 - (y - ey) * s
            reach = max(size[:2]) / 2 * s + 2
            if not (reach < u < w - reach and reach < v < h - reach) or (u < 0.3 * w and v < 0.35 * h):
                continue  # outside the view, or under the legend
            r, g, b = category_rgb(str(name))
            window = image[int(v - reach):int(v + reach) + 1, int(u - reach):int(u + reach) + 1]
            total += 1
            seen += bool((np.abs(window - [b, g, r]).max(axis=2) <= 2).any())
    assert total >= 5
    assert seen >= 0.8 * total, (seen, total)


def test_the_legend_explains_the_height_colouring_unless_told_otherwise():
    """draw_legend's default point colouring is the height scale (its bar and range): the same pixels as asked
    for by name, and not those of another colouring's line."""
    from nuparquet.rendering.bev import draw_legend

    by_default, by_name, other = (np.full((600, 600, 3), 120, np.uint8) for _ in range(3))
    draw_legend(by_default)
    draw_legend(by_name, points="height")
    draw_legend(other, points="intensity")
    assert np.array_equal(by_default, by_name) and not np.array_equal(by_default, other)


def test_a_view_smaller_than_its_legend_gets_the_legend_cut_at_its_edge(synth_out, tmp_path):
    """The legend's panel and its height bar end where a small view ends (a 96 px view raised a broadcast error),
    and a larger view's legend is the small one's, uncut."""
    from nuparquet.rendering.bev import draw_legend

    small, large = np.full((96, 96, 3), 120, np.uint8), np.full((300, 300, 3), 120, np.uint8)
    draw_legend(small, points="height", map_layers=True)
    draw_legend(large, points="height", map_layers=True)
    assert (small != 120).any() and np.array_equal(small, large[:96, :96])  # the same font at both sizes
    assert main(["render", str(synth_out), "--scene", SCENE, "--channel", "bev", "--bev-size", "96",
                 "--out", str(tmp_path / "small.mp4"), "--quiet"]) == 0


def test_an_all_frames_bev_video_runs_at_the_lidars_own_rate(synth_out, tmp_path):
    """--channel bev --all-frames without --fps: one picture per LIDAR_TOP frame, at the rate of its frames
    (1 / the median step between them, rounded), not the keyframes' default."""
    out = tmp_path / "bev.mp4"
    assert main(["render", str(synth_out), "--scene", SCENE, "--channel", "bev", "--all-frames", "--bev-size", "200",
                 "--out", str(out), "--quiet"]) == 0
    times = (nuparquet.open(synth_out).scan("frames")
             .filter((pl.col("scene_name") == SCENE) & (pl.col("channel").cast(pl.String) == "LIDAR_TOP"))
             .sort("timestamp").collect()["timestamp"].to_numpy())
    expected = round(1e6 / float(np.median(np.diff(times))))
    with av.open(str(out)) as container:
        stream = container.streams.video[0]
        rate, frames = float(stream.average_rate), sum(1 for _ in container.decode(stream))
    assert frames == len(times) and rate == expected > 2


def test_the_ego_is_drawn_at_the_centre_with_its_front_marked_ahead(map_out, tmp_path):
    """With the ego up, its front's red dot is straight above the picture's centre, half the ego's length away."""
    from nuparquet.rendering.bev import EGO_SIZE_LW_M

    assert main(["render", str(map_out), "--scene", SCENE, "--channel", "bev", "--frames-dir", str(tmp_path / "frames"),
                 "--frame-format", "png", "--quiet", "--bev-range-m", "30", "--bev-size", "400"]) == 0
    image = cv2.imread(str(tmp_path / "frames" / "00000.png"))
    h, w = image.shape[:2]
    s = h / (2 * 30.0)
    tip_u, tip_v = (w - 1) / 2, (h - 1) / 2 - EGO_SIZE_LW_M[0] / 2 * s
    red = np.argwhere((image[:, :, 0] < 40) & (image[:, :, 1] < 40) & (image[:, :, 2] > 215))  # (v, u)
    near = red[np.hypot(red[:, 1] - tip_u, red[:, 0] - tip_v) <= 4]
    assert len(near) >= 5
    assert abs(near[:, 1].mean() - tip_u) <= 1.5 and abs(near[:, 0].mean() - tip_v) <= 1.5


def test_road_dividers_are_drawn_two_pixels_wide_and_lane_dividers_one(map_out, monkeypatch):
    """The BEV map raster strokes a road divider 2 px wide and a lane divider 1 px: the pixels each layer changes
    (the raster with it against the raster without it, anti-aliased edges included) per pixel of its lines' length,
    at 10 px/m over every divider of a map."""
    import shapely

    from nuparquet.rendering import bev

    ds = nuparquet.open(map_out)
    location = ds.scan("scenes").filter(pl.col("name") == SCENE).collect()["log_location"][0]
    layers = ds.map(location)
    style = bev.MAP_STYLE
    widths = {}
    for layer in ("road_divider", "lane_divider"):
        lines = [g for g in layers.layers[layer].geometry if g is not None and not g.is_empty]
        assert lines, layer
        x0, y0, x1, y1 = shapely.total_bounds(np.array(lines, dtype=object))
        extent = (x0 - 5, y0 - 5, x1 + 5, y1 + 5)
        with_layer = bev.MapRaster.build(layers, extent, 10.0).image
        monkeypatch.setattr(bev, "MAP_STYLE", tuple(entry for entry in style if entry[0] != layer))
        without = bev.MapRaster.build(layers, extent, 10.0).image
        monkeypatch.setattr(bev, "MAP_STYLE", style)
        changed = (with_layer != without).any(axis=2).sum()
        widths[layer] = changed / (sum(line.length for line in lines) * 10.0)
    # anti-aliasing adds about a pixel to each side of a stroke: 2 + 2 against 1 + 2, give or take the line ends
    assert widths["road_divider"] - widths["lane_divider"] > 1.0 and 1.5 < widths["lane_divider"] < 3.5, widths
