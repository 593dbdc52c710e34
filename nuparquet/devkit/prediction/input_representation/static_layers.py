"""The devkit's `input_representation.static_layers`: the map around an agent as a three-channel image (its layers'
masks in colour, the lanes within 50 m coloured by their heading against the agent's), turned so the agent heads
up, pixel for pixel as the devkit draws it.

The map is the converted one, `Dataset.map(location)` (`nuparquet.map.queries.MapLayers`): `map_mask` is
`get_map_mask`, `records_in_radius` is `get_records_in_radius`, and the lane poses are the map's centrelines,
discretised once per map (`MapLayers.centerlines`, the devkit's `discretize_lanes` pose for pose) instead of per
raster. `load_all_maps` and `get_lanes_in_radius` take and give these `MapLayers` where the devkit's take its
`NuScenesMap`.

The raster is the devkit's, computed on less: every step after the masks is per pixel, so each image is cropped to
the agent's window first (and the lanes' rotation asked for that window only, `utils.rotate_and_crop`); the lanes'
pixels and colours are computed for all segments at once and drawn with the devkit's `cv2.line` calls, in its
order (a later segment paints over an earlier one).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import cv2
import numpy as np
from pyquaternion import Quaternion

from nuparquet.devkit.prediction.helper import _angle_diffs, angle_of_rotation, quaternion_yaw
from nuparquet.devkit.prediction.input_representation.combinators import Rasterizer
from nuparquet.devkit.prediction.input_representation.interface import StaticLayerRepresentation
from nuparquet.devkit.prediction.input_representation.utils import get_crops, pixel_coords, rotate_and_crop

if TYPE_CHECKING:
    from nuparquet.map.queries import MapLayers

Color = tuple[float, float, float]
LANE_RADIUS_M = 50  # the devkit draws the lanes within 50 m of the agent, discretised every 1 m
LANE_DISCRETIZATION_M = 1


def load_all_maps(helper, verbose: bool = False) -> dict[str, MapLayers]:
    """{location: its `MapLayers`} for every map of the helper's converted output (the devkit's loads the four
    nuScenes maps' JSON; here the maps the conversion holds, sorted by name).

    Raises:
        UsageError: the output holds no map (converted with --no-map, or from a dataroot without maps/expansion).
    """
    import polars as pl

    from nuparquet.errors import UsageError

    dataset = helper.data._dataset
    if "map/lane" not in dataset.datasets:
        raise UsageError(f"{dataset.root} has no map/ datasets: convert a dataroot holding maps/expansion/*.json "
                         "(without --no-map)")
    locations = dataset.scan("map/lane").select(pl.col("location").unique().sort()).collect()["location"]
    maps = {}
    for map_name in locations.to_list():
        if verbose:
            print(f'static_layers.py - Loading Map: {map_name}')
        maps[map_name] = dataset.map(map_name)
    return maps


def get_patchbox(x_in_meters: float, y_in_meters: float, image_side_length: float
                 ) -> tuple[float, float, float, float]:
    """The patch (x_center, y_center, height, width) of a square image centred on (x, y)."""
    return (x_in_meters, y_in_meters, image_side_length, image_side_length)


def change_color_of_binary_mask(image: np.ndarray, color: Color) -> np.ndarray:
    """A 0/1 three-channel image painted `color` where 1, as uint8 (the devkit's product, then its cast)."""
    return (image * color).astype("uint8")


def _colored_mask(mask: np.ndarray, color: Color) -> np.ndarray:
    """(H, W, 3) `change_color_of_binary_mask` of a (H, W) 0/1 mask repeated on 3 channels: the two colours it can
    give, computed by it, then looked up per pixel."""
    values = change_color_of_binary_mask(np.repeat(np.array([[0], [1]], mask.dtype), 3, 1), color)
    return np.take(values, mask, axis=0)


def correct_yaw(yaw: float) -> float:
    """The yaw to turn a map patch by: the maps are flipped over the y axis, so pi is added."""
    if yaw <= 0:
        yaw = -np.pi - yaw
    else:
        yaw = np.pi - yaw
    return yaw


class LaneCenterlines:
    """A map's lane and lane connector poses at one resolution, discretised once (`MapLayers.centerlines`), and
    the lanes near a point as the devkit's `get_lanes_in_radius` finds them."""

    def __init__(self, map_api: MapLayers, resolution_m: float):
        self.map_api = map_api
        self.poses, counts = map_api.centerlines(resolution_m)  # (N, 3), lanes then connectors, file order
        self.start = np.r_[0, np.cumsum(counts)]
        tokens = np.concatenate([map_api.layers[layer].tokens for layer in ("lane", "lane_connector")])
        self.row_of = {token: i for i, token in enumerate(tokens.tolist())}

    def in_radius(self, x: float, y: float, radius: float) -> dict[str, np.ndarray]:
        """{token: (P, 3) poses [x, y, yaw]} of the lanes, then lane connectors, whose polygon meets the square of
        half-side `radius` around (x, y) (`get_records_in_radius`), each in file order.

        Raises:
            UsageError: a lane has no arcline path (the devkit's `discretize_lanes` raises KeyError).
        """
        records = self.map_api.records_in_radius(x, y, radius, ["lane", "lane_connector"])
        tokens = records["lane"] + records["lane_connector"]
        missing = [t for t in tokens if t not in self.map_api.arcline_path_3]
        if missing:
            self.map_api.discretize_lanes(missing, 1.0)  # raises its UsageError naming them
        rows = [self.row_of[t] for t in tokens]
        return {t: self.poses[self.start[r]:self.start[r + 1]] for t, r in zip(tokens, rows)}


def get_lanes_in_radius(x: float, y: float, radius: float, discretization_meters: float,
                        map_api: MapLayers) -> dict[str, list[tuple[float, float, float]]]:
    """{lane token: its poses (x, y, yaw)} of the lanes and lane connectors within `radius` m of (x, y), poses every
    ~`discretization_meters` m, in the devkit's order (lanes, then connectors, file order)."""
    lanes = LaneCenterlines(map_api, discretization_meters).in_radius(x, y, radius)
    return {token: [tuple(pose) for pose in poses.tolist()] for token, poses in lanes.items()}


def hsv_to_rgb(h: np.ndarray, s: float, v: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`colorsys.hsv_to_rgb` of every (N,) hue (s > 0), operation for operation."""
    h6 = h * 6.0
    i = np.trunc(h6)  # int() truncates
    f = h6 - i
    p = np.full_like(f, v * (1.0 - s))
    q = v * (1.0 - s * f)
    t = v * (1.0 - s * (1.0 - f))
    vv = np.full_like(f, v)
    sector = (i.astype(np.int64) % 6)[:, None]
    choices = [(vv, t, p), (q, vv, p), (p, vv, t), (p, q, vv), (t, p, vv), (vv, p, q)]
    rgb = np.select([sector == k for k in range(6)], [np.stack(c, 1) for c in choices])
    return rgb[:, 0], rgb[:, 1], rgb[:, 2]


def colors_by_yaw(agent_yaw_in_radians: float, lane_yaws_in_radians: np.ndarray) -> np.ndarray:
    """(N, 3) `color_by_yaw` of (N,) lane poses: hue from the yaw difference, lanes heading the agent's way blue."""
    lane_yaws = np.asarray(lane_yaws_in_radians, np.float64)
    angle = _angle_diffs(np.full(len(lane_yaws), agent_yaw_in_radians, np.float64), lane_yaws, 2 * np.pi) + np.pi
    angle = angle * 180 / np.pi
    r, g, b = hsv_to_rgb(angle / 360, 1., 1.)
    return np.stack([r * 255, g * 255, b * 255], 1)


def color_by_yaw(agent_yaw_in_radians: float, lane_yaw_in_radians: float) -> Color:
    """The RGB colour of a lane pose by its yaw difference to the agent's (0-255 floats)."""
    r, g, b = colors_by_yaw(agent_yaw_in_radians, np.array([lane_yaw_in_radians], np.float64))[0]
    return r, g, b


def draw_lanes_on_image(image: np.ndarray, lanes: dict, agent_global_coords: tuple[float, float],
                        agent_yaw_in_radians: float, agent_pixels: tuple[int, int], resolution: float,
                        color_function: Callable[[float, float], Color] = color_by_yaw) -> np.ndarray:
    """`image` with each lane's consecutive poses joined by 5 px lines, each coloured by
    `color_function(agent_yaw, yaw of its first pose)`; `lanes` is {token: poses (x, y, yaw)} (lists or (P, 3)
    arrays); `agent_pixels` is the agent's (row, column). Draws in place and returns `image`."""
    arrays = [np.asarray(poses, np.float64).reshape(-1, 3) for poses in lanes.values()]
    starts = np.concatenate([a[:-1] for a in arrays] or [np.zeros((0, 3))])
    ends = np.concatenate([a[1:] for a in arrays] or [np.zeros((0, 3))])
    if not len(starts):
        return image
    start_rows, start_columns = pixel_coords(starts[:, 0], starts[:, 1], agent_global_coords, agent_pixels, resolution)
    end_rows, end_columns = pixel_coords(ends[:, 0], ends[:, 1], agent_global_coords, agent_pixels, resolution)
    if color_function is color_by_yaw:
        colors = colors_by_yaw(agent_yaw_in_radians, starts[:, 2]).tolist()
    else:
        colors = [color_function(agent_yaw_in_radians, yaw) for yaw in starts[:, 2].tolist()]
    # OpenCV takes (column, row); one call per segment, in order, as overlapping segments paint over each other
    for c0, r0, c1, r1, color in zip(start_columns.tolist(), start_rows.tolist(), end_columns.tolist(),
                                     end_rows.tolist(), colors):
        cv2.line(image, (c0, r0), (c1, r1), color, thickness=5)
    return image


def draw_lanes_in_agent_frame(image_side_length: int, agent_x: float, agent_y: float, agent_yaw: float,
                              radius: float, image_resolution: float, discretization_resolution_meters: float,
                              map_api: MapLayers,
                              color_function: Callable[[float, float], Color] = color_by_yaw) -> np.ndarray:
    """(L, L, 3) uint8: the lanes within `radius` m of the agent drawn around the image centre, then turned so
    the agent heads up."""
    lanes = LaneCenterlines(map_api, discretization_resolution_meters).in_radius(agent_x, agent_y, radius)
    return _lanes_in_agent_frame(image_side_length, agent_x, agent_y, agent_yaw, lanes, image_resolution,
                                 color_function, slice(None), slice(None))


def _lanes_in_agent_frame(image_side_length: int, agent_x: float, agent_y: float, agent_yaw: float, lanes: dict,
                          image_resolution: float, color_function, row_crop: slice, col_crop: slice) -> np.ndarray:
    agent_pixels = int(image_side_length / 2), int(image_side_length / 2)
    image = np.zeros((image_side_length, image_side_length, 3))
    draw_lanes_on_image(image, lanes, (agent_x, agent_y), agent_yaw, agent_pixels, image_resolution, color_function)
    return rotate_and_crop(image, agent_yaw, row_crop, col_crop)


class StaticLayerRasterizer(StaticLayerRepresentation):
    """The map layers around an agent, each in its colour, with the lanes on top, as a three-channel image of the
    agent's window (`meters_ahead` up, `meters_behind`, `meters_left`, `meters_right`; `resolution` m per pixel)."""

    def __init__(self, helper, layer_names: list[str] | None = None, colors: list[Color] | None = None,
                 resolution: float = 0.1, meters_ahead: float = 40, meters_behind: float = 10,
                 meters_left: float = 25, meters_right: float = 25):
        self.helper = helper
        self.maps = load_all_maps(helper)
        self.layer_names = layer_names or ['drivable_area', 'ped_crossing', 'walkway']
        self.colors = colors or [(255, 255, 255), (119, 136, 153), (0, 0, 255)]
        self.resolution = resolution
        self.meters_ahead = meters_ahead
        self.meters_behind = meters_behind
        self.meters_left = meters_left
        self.meters_right = meters_right
        self.combinator = Rasterizer()
        self._centerlines: dict[str, LaneCenterlines] = {}

    def make_representation(self, instance_token: str, sample_token: str) -> np.ndarray:
        """(rows, columns, 3) uint8 image of the map around the instance at the sample."""
        sample_annotation = self.helper.get_sample_annotation(instance_token, sample_token)
        map_name = self.helper.get_map_name_from_sample_token(sample_token)
        x, y = sample_annotation['translation'][:2]
        yaw = quaternion_yaw(Quaternion(sample_annotation['rotation']))
        yaw_corrected = correct_yaw(yaw)
        image_side_length = 2 * max(self.meters_ahead, self.meters_behind, self.meters_left, self.meters_right)
        image_side_length_pixels = int(image_side_length / self.resolution)
        patchbox = get_patchbox(x, y, image_side_length)
        angle_in_degrees = angle_of_rotation(yaw_corrected) * 180 / np.pi
        canvas_size = (image_side_length_pixels, image_side_length_pixels)
        map_api = self.maps[map_name]
        masks = map_api.map_mask(patchbox, angle_in_degrees, self.layer_names, canvas_size=canvas_size)
        row_crop, col_crop = get_crops(self.meters_ahead, self.meters_behind, self.meters_left, self.meters_right,
                                       self.resolution, image_side_length_pixels)
        images = [_colored_mask(mask[::-1][row_crop, col_crop], color) for mask, color in zip(masks, self.colors)]
        if map_name not in self._centerlines:
            self._centerlines[map_name] = LaneCenterlines(map_api, LANE_DISCRETIZATION_M)
        lanes = self._centerlines[map_name].in_radius(x, y, LANE_RADIUS_M)
        images.append(_lanes_in_agent_frame(image_side_length_pixels, x, y, yaw, lanes, self.resolution,
                                            color_by_yaw, row_crop, col_crop))
        return self.combinator.combine(images)
