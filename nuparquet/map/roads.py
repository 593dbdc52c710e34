"""Records by their shape: a record's bounds, and the roads that follow the one under a point, as the devkit's
`NuScenesMap.get_bounds` and `get_next_roads` answer.

`get_bounds` is the extent of the record's nodes (a polygon record's exterior: its polygon's, drivable_area's every
polygon's; a line record's line), which is the extent of the stored geometry. `get_next_roads` picks the finest road
record under the point (lane, else road_block, else road_segment), takes every road record intersecting that
record's bounds, and keeps those sharing a node with a road segment's exterior, or holding every node of a lane's or
road block's `to_edge_line`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import shapely

from nuparquet.map.layers import LINE_LAYERS, POLYGON_LAYERS

if TYPE_CHECKING:
    from nuparquet.map.queries import MapLayers

ROAD_LAYERS = ("road_segment", "road_block", "lane")  # coarse to fine


def bounds(layers: MapLayers, layer: str, token: str) -> tuple[float, float, float, float]:
    """(x_min, y_min, x_max, y_max) of a record of a polygon or line layer (`NuScenesMap.get_bounds`)."""
    if layer not in POLYGON_LAYERS + LINE_LAYERS:
        raise ValueError(f"{layer} is not a valid layer")
    records = layers.layers[layer]
    found = np.flatnonzero(records.tokens == token)
    if not len(found):
        raise KeyError(f"no {layer} record {token!r} in the map of {layers.location}")
    geometry = records.geometry[found[0]]
    if geometry is None or shapely.is_empty(geometry):
        raise ValueError(f"{layer} record {token!r} has no nodes")
    x_min, y_min, x_max, y_max = shapely.bounds(geometry).tolist()
    return x_min, y_min, x_max, y_max


def next_roads(layers: MapLayers, x: float, y: float) -> dict[str, list[str]]:
    """{road_segment, road_block, lane: tokens} of the roads that may follow the finest one at (x, y)
    (`NuScenesMap.get_next_roads`); ValueError when no road record holds the point."""
    on_point = {layer: tokens[0] for layer, tokens in layers.layers_on_point(x, y, ROAD_LAYERS).items()}
    current = next(((layer, on_point[layer]) for layer in reversed(ROAD_LAYERS) if on_point[layer]), None)
    if current is None:
        raise ValueError(f"no road_segment, road_block or lane at ({x}, {y})")
    layer, token = current
    candidates = layers.records_in_patch(bounds(layers, layer, token), ROAD_LAYERS, mode="intersect")
    exterior = {name: layers.exterior_nodes(name) for name in ROAD_LAYERS}
    if layer == "road_segment":  # no direction: any shared exterior node
        wanted = exterior[layer][token]
        follows = lambda nodes: any(n in nodes for n in wanted)  # noqa: E731
    else:  # a lane or road block ends at its to_edge_line: every node of it on the next road's exterior
        wanted = layers.line_node_tokens(layers.record_field(layer, token, "to_edge_line_token"))
        follows = lambda nodes: all(n in nodes for n in wanted)  # noqa: E731
    return {name: [t for t in candidates[name] if follows(exterior[name][t]) and t != on_point[name]]
            for name in ROAD_LAYERS}
