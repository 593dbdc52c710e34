"""Pictures of the map expansion, as `NuScenesMap`'s renderers show it, north up, drawn with OpenCV (`map_canvas`):

- `render_map_patch`: the layers over a rectangle (plus the devkit's margins), its outline and size, a legend;
- `render_layers`: layers over the whole map, optionally only some records; `render_record`: one record in the whole
  map and close up; `render_next_roads`: the roads that may follow a point;
- `render_map_mask`: `get_map_mask`'s masks side by side, as the devkit's `imshow(origin='lower')` shows them;
- `render_centerlines`: every lane's centreline; `render_egoposes_on_map`: the ego poses of scenes over the map.

Colours are the devkit explorer's (`palette.MAP_LAYER_RGB`), polygons blended at `alpha` over a white background.
Returns (H, W, 3) uint8 RGB.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
import polars as pl
import shapely

from nuparquet.dataset import as_dataset
from nuparquet.errors import UsageError
from nuparquet.map.layers import NON_GEOMETRIC_LAYERS, POLYGON_LAYERS
from nuparquet.rendering import legend
from nuparquet.rendering.map_canvas import MapCanvas, layer_geometries
from nuparquet.rendering.palette import LINE_CYCLE_RGB, MAP_LAYER_RGB
from nuparquet.rendering.point_colors import scalar_rgb

REPRESENTATIVE_LAYERS = ("drivable_area", "lane", "walkway")  # the explorer's default other_layers
RED, BLACK = (255, 0, 0), (0, 0, 0)
MAP_SIZE_PX = 1000


def _rgb(image_bgr: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(image_bgr[..., ::-1])


def map_extent(dataset, location: str) -> tuple[float, float, float, float]:
    """(0, 0, canvas_edge_x, canvas_edge_y) of a map (the devkit's canvas: recorded in the map files' metadata), else
    the extent of its nodes."""
    import json

    import pyarrow.parquet as pq

    if not dataset.is_remote:
        for path, _ in dataset.files("map/node")[:1]:
            metadata = pq.read_schema(path).metadata or {}
            maps = json.loads(metadata.get(b"nuparquet.map", b"{}")).get("maps", {})
            edge = maps.get(location, {}).get("canvas_edge_m")
            if edge:
                return 0.0, 0.0, float(edge[0]), float(edge[1])
    nodes = dataset.scan("map/node").filter(pl.col("location") == location).select("x", "y").collect()
    return (float(nodes["x"].min()), float(nodes["y"].min()), float(nodes["x"].max()), float(nodes["y"].max()))


def draw_layers(canvas: MapCanvas, map_layers, layer_names: Sequence[str], alpha: float,
                tokens: Sequence[str] | None = None) -> None:
    """The layers in the order given (polygons blended, lines, traffic lights as arrows from their first node)."""
    for layer in layer_names:
        if layer not in NON_GEOMETRIC_LAYERS:
            raise UsageError(f"{layer} is not a layer the map draws; layers: {', '.join(NON_GEOMETRIC_LAYERS)}")
        geoms = layer_geometries(map_layers, layer, canvas.box, tokens)
        colour = MAP_LAYER_RGB[layer]
        if layer in POLYGON_LAYERS:
            canvas.fill(geoms, colour, alpha)
        elif layer == "traffic_light":
            lines = [g for g in geoms if g is not None and shapely.get_num_points(g) >= 2]
            if lines:
                starts = np.array([np.asarray(g.coords)[0] for g in lines])
                ends = np.array([np.asarray(g.coords)[1] for g in lines])
                canvas.arrows(starts, ends, colour)
        else:
            canvas.lines(geoms, colour, 2, alpha)


def _layer_legend(canvas: MapCanvas, layer_names: Sequence[str]) -> None:
    legend.draw_legend(canvas.image, [(layer, MAP_LAYER_RGB[layer]) for layer in dict.fromkeys(layer_names)],
                       corner="top-right")


def render_map_patch(dataset_or_path, location: str, box_coords, layer_names: Sequence[str] | None = None,
                     alpha: float = 0.5, render_egoposes_range: bool = True, render_legend: bool = True, *,
                     size_px: int = MAP_SIZE_PX, poses_xy=None) -> np.ndarray:
    """The map of `location` over `box_coords` (x_min, y_min, x_max, y_max) with the devkit's margins (a quarter of
    the side, at most 50 m across and 10 m up and down), `layer_names` (default every layer) drawn in order, the
    rectangle dash-dotted in red with its size, and a legend; `poses_xy` (N, 2) adds ego poses as black dots."""
    dataset = as_dataset(dataset_or_path)
    x_min, y_min, x_max, y_max = (float(v) for v in box_coords)
    width, height = x_max - x_min, y_max - y_min
    if height <= 0 or width <= 0:
        raise UsageError(f"the map patch {box_coords} has no area (x_min, y_min, x_max, y_max)")
    layer_names = list(layer_names or NON_GEOMETRIC_LAYERS)
    x_margin, y_margin = min(width / 4, 50), min(height / 4, 10)
    canvas = MapCanvas.create((x_min - x_margin, y_min - y_margin, x_max + x_margin, y_max + y_margin), size_px)
    draw_layers(canvas, dataset.map(location), layer_names, alpha)
    if poses_xy is not None and len(poses_xy):
        canvas.dots(poses_xy, BLACK, max(2, size_px // 300))
    if render_egoposes_range:
        canvas.rectangle(x_min, y_min, x_max, y_max, RED, 2, dash_px=max(4, size_px // 100))
        canvas.text((x_min + width / 100, y_min + height / 2), f"{height:g} m")
        canvas.text((x_min + width / 2, y_min + height / 100), f"{width:g} m")
    if render_legend:
        _layer_legend(canvas, layer_names)
    return _rgb(canvas.image)


def render_layers(dataset_or_path, location: str, layer_names: Sequence[str], alpha: float = 0.5,
                  tokens: Sequence[str] | None = None, *, size_px: int = MAP_SIZE_PX, extent=None) -> np.ndarray:
    """`layer_names` over the whole map of `location` (its canvas), only the records `tokens` when given."""
    dataset = as_dataset(dataset_or_path)
    canvas = MapCanvas.create(extent or map_extent(dataset, location), size_px)
    draw_layers(canvas, dataset.map(location), list(layer_names), alpha, tokens)
    _layer_legend(canvas, list(layer_names))
    return _rgb(canvas.image)


def render_record(dataset_or_path, location: str, layer_name: str, token: str, alpha: float = 0.5,
                  other_layers: Sequence[str] | None = None, *, size_px: int = MAP_SIZE_PX) -> np.ndarray:
    """One record: the whole map with the close-up's rectangle (left) beside the close-up, the record's bounds and a
    third of their size around them (drivable_area: the bounds alone), the bounds dash-dotted in red (right)."""
    dataset = as_dataset(dataset_or_path)
    map_layers = dataset.map(location)
    layers = list(dict.fromkeys(list(other_layers if other_layers is not None else REPRESENTATIVE_LAYERS)
                                 + [layer_name]))
    x1, y1, x2, y2 = map_layers.bounds(layer_name, token)
    dx, dy = ((0.0, 0.0) if layer_name == "drivable_area" else ((x2 - x1) / 3, (y2 - y1) / 3))
    whole = MapCanvas.create(map_extent(dataset, location), size_px)
    local = MapCanvas.create((x1 - dx, y1 - dy, x2 + dx, y2 + dy), height_px=whole.image.shape[0])
    draw_layers(local, map_layers, layers, alpha)
    if layer_name != "drivable_area":
        local.rectangle(x1, y1, x2, y2, RED, 2, dash_px=max(4, size_px // 100))
    legend.draw_caption(local.image, "local view", corner="top-left")
    draw_layers(whole, map_layers, layers, alpha)
    whole.rectangle(local.x_min, local.y_min, local.x_max, local.y_max, BLACK, 2)
    _layer_legend(whole, layers)
    legend.draw_caption(whole.image, "global view", corner="top-left")
    return _rgb(_side_by_side([whole.image, local.image]))


def _side_by_side(images: Sequence[np.ndarray], gap_px: int = 6) -> np.ndarray:
    """Pictures in a row, each scaled to the height of the first, white gaps between."""
    height = images[0].shape[0]
    scaled = [im if im.shape[0] == height else cv2.resize(im, (max(2, round(im.shape[1] * height / im.shape[0])),
                                                              height), interpolation=cv2.INTER_AREA) for im in images]
    gap = np.full((height, gap_px, 3), 255, np.uint8)
    return np.concatenate([piece for im in scaled for piece in (im, gap)][:-1], axis=1)


def render_map_mask(dataset_or_path, location: str, patch_box, patch_angle: float,
                    layer_names: Sequence[str] | None = None, canvas_size=(100, 100), n_row: int = 2, *,
                    tile_px: int = 400) -> np.ndarray:
    """`get_map_mask`'s masks (`MapLayers.map_mask`) in a grid of `n_row` rows, each as the devkit's
    `imshow(origin='lower')` shows it (viridis, the mask's first row at the bottom), named."""
    dataset = as_dataset(dataset_or_path)
    layer_names = list(layer_names or NON_GEOMETRIC_LAYERS)
    masks = dataset.map(location).map_mask(tuple(patch_box), patch_angle, layer_names, canvas_size)
    names = [name for name in layer_names if name != "traffic_light"]  # get_map_mask gives traffic lights no mask
    n_row = max(1, min(n_row, len(masks)))
    n_col = -(-len(masks) // n_row)
    height, width = masks.shape[1:] if len(masks) else canvas_size
    tile_h = tile_px
    tile_w = max(2, round(tile_px * width / max(height, 1)))
    tiles = []
    for mask, name in zip(masks, names):
        shown = scalar_rgb(mask.reshape(-1)).reshape(mask.shape + (3,))[::-1, :, ::-1]  # origin lower; BGR
        tile = cv2.resize(np.ascontiguousarray(shown), (tile_w, tile_h), interpolation=cv2.INTER_NEAREST)
        legend.draw_caption(tile, name, corner="top-left")
        tiles.append(tile)
    grid = np.full((n_row * tile_h + (n_row - 1) * 6, n_col * tile_w + (n_col - 1) * 6, 3), 255, np.uint8)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, n_col)
        grid[r * (tile_h + 6):r * (tile_h + 6) + tile_h, c * (tile_w + 6):c * (tile_w + 6) + tile_w] = tile
    return _rgb(grid)


def render_centerlines(dataset_or_path, location: str, resolution_meters: float = 0.5, *,
                       size_px: int = MAP_SIZE_PX, extent=None) -> np.ndarray:
    """Every lane's then every lane connector's centreline (`discretize_centerlines`), lane i in the i-th colour of
    matplotlib's cycle, as the devkit's `plt.plot` per lane gives them, over the whole map (or `extent`: x_min,
    y_min, x_max, y_max)."""
    dataset = as_dataset(dataset_or_path)
    map_layers = dataset.map(location)
    poses, counts = map_layers.centerlines(resolution_meters)
    canvas = MapCanvas.create(extent or map_extent(dataset, location), size_px)
    starts = np.r_[0, np.cumsum(counts)]
    drawn = 0
    for lane, (lo, hi) in enumerate(zip(starts[:-1], starts[1:])):
        if hi - lo < 1:
            continue
        canvas.lines([shapely.linestrings(poses[lo:hi, :2]) if hi - lo > 1 else shapely.points(poses[lo, :2])],
                     LINE_CYCLE_RGB[drawn % len(LINE_CYCLE_RGB)], 2)
        drawn += 1
    return _rgb(canvas.image)


def ego_poses_on_map(dataset, location: str, scene_tokens: Sequence[str] | None = None) -> np.ndarray:
    """(N, 2) x, y of the reference lidar keyframes' ego poses of the scenes at `location` (scene file order, then
    sample file order; only `scene_tokens` when given), as `render_egoposes_on_fancy_map` collects them."""
    scenes = (dataset.scan("tables/scene").with_row_index("_scene").join(
        dataset.scan("scenes").select(pl.col("token"), "log_location"), on="token", how="inner")
        .filter(pl.col("log_location") == location).select("token", "_scene").collect())
    if scene_tokens is not None:
        scenes = scenes.filter(pl.col("token").is_in(list(scene_tokens)))
    if scenes.is_empty():
        raise UsageError(f"no scene at {location!r}" + (" among the scenes given" if scene_tokens is not None else ""))
    samples = (dataset.scan("tables/sample").with_row_index("_sample").select("token", "scene_token", "_sample")
               .collect().join(scenes.rename({"token": "scene_token"}), on="scene_token", how="inner"))
    reference = dataset.channels.get("reference_lidar")
    poses = (dataset.scan("frames").filter(pl.col("is_key_frame") & (pl.col("channel").cast(pl.String) == reference))
             .select(pl.col("sample_token").alias("token"), "ego_translation").collect())
    ordered = samples.join(poses, on="token", how="inner").sort("_scene", "_sample")
    from nuparquet.columns import to_numpy

    return to_numpy(ordered["ego_translation"], (3,))[:, :2]


def render_egoposes_on_map(dataset_or_path, log_location: str, scene_tokens: Sequence[str] | None = None, *,
                           render_egoposes_range: bool = True, render_legend: bool = True,
                           size_px: int = MAP_SIZE_PX) -> np.ndarray:
    """The ego poses of the scenes at `log_location` (`ego_poses_on_map`) as black dots over the map patch around
    them: the devkit's `render_egoposes_on_fancy_map` (2 m margin rounded out to whole metres, at least 30 m)."""
    dataset = as_dataset(dataset_or_path)
    poses = ego_poses_on_map(dataset, log_location, scene_tokens)
    low, high = np.floor(poses.min(axis=0) - 2), np.ceil(poses.max(axis=0) + 2)
    size = high - low
    if any(size < 30):
        centre = (low + high) / 2
        size = np.maximum(size, 30)
        low, high = centre - size / 2, centre + size / 2
    return render_map_patch(dataset, log_location, (low[0], low[1], high[0], high[1]), NON_GEOMETRIC_LAYERS,
                            render_egoposes_range=render_egoposes_range, render_legend=render_legend,
                            size_px=size_px, poses_xy=poses)


def render_next_roads(dataset_or_path, location: str, x: float, y: float, alpha: float = 0.5, *,
                      size_px: int = MAP_SIZE_PX, margin_m: float = 20.0) -> np.ndarray:
    """The roads that may follow the one at (x, y) (`MapLayers.next_roads`), their layers only, with a red x at the
    point; framed on those roads and the point (`margin_m` around), where the devkit shows the whole map."""
    dataset = as_dataset(dataset_or_path)
    map_layers = dataset.map(location)
    roads = map_layers.next_roads(x, y)
    layers = [layer for layer, tokens in roads.items() if tokens]
    tokens = [t for layer in layers for t in roads[layer]]
    bounds = np.array([map_layers.bounds(layer, t) for layer in layers for t in roads[layer]] + [[x, y, x, y]])
    extent = (bounds[:, 0].min() - margin_m, bounds[:, 1].min() - margin_m, bounds[:, 2].max() + margin_m,
              bounds[:, 3].max() + margin_m)
    canvas = MapCanvas.create(extent, size_px)
    draw_layers(canvas, map_layers, layers, alpha, tokens)
    u, v = np.rint(canvas.to_pixels([[x, y]])[0]).astype(int).tolist()
    cv2.drawMarker(canvas.image, (u, v), (0, 0, 255), cv2.MARKER_TILTED_CROSS, max(12, size_px // 60), 2, cv2.LINE_AA)
    _layer_legend(canvas, layers)
    return _rgb(canvas.image)

