"""Map expansion files (`maps/expansion/<location>.json`, version 1.3) consistent with the synthetic roads.

Every scene drives along its own road (`synth.road.Road`); a location's map holds the road of every scene of
that location. Along each road, in right-hand-traffic lateral offsets (mirrored where traffic keeps left, like
the object rows of `synth.world`):

    walkway  [-13.5, -9.0]            pedestrians and curb objects (world rows at -10.0 .. -12.2)
    drivable [-9.0, 12.0]             parking rows, bike lane, four lanes; one hole (a median island) per map
    lanes    [-5.25, -1.75] [-1.75, 1.75] (with s)    [1.75, 5.35] [5.35, 8.95] (against s)
    walkway  [12.0, 16.5]

The road is cut into pieces of `PIECE_M`; every `INTERSECTION_EVERY`-th piece is an intersection: its lane pieces
are lane connectors, its road segment says `is_intersection`, a ped crossing spans its start, and stop lines
(one at a traffic light) stand before it. Lane centrelines are arcline paths (one constant-curvature path per
`ARC_M`), connectivity links each lane piece to the next in its direction. One carpark over the right parking
row, road and lane dividers along the road. The layout (field names, key order, nesting) is the devkit's
(`nuscenes.map_expansion.map_api`); values are floats where the real files hold floats.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from nuparquet.synth.road import Road
from nuparquet.synth.tokens import random_tokens

VERSION = "1.3"
PIECE_M = 30.0
ARC_M = 10.0
EDGE_STEP_M = 10.0
INTERSECTION_EVERY = 4
DRIVABLE_M = (-9.0, 12.0)
WALKWAYS_M = ((-13.5, -9.0), (12.0, 16.5))
LANES_M = ((-5.25, -1.75, +1), (-1.75, 1.75, +1), (1.75, 5.35, -1), (5.35, 8.95, -1))  # (right, left edge, direction)
ROAD_DIVIDER_M = 1.75
LANE_DIVIDERS_M = (-1.75, 5.35)
CARPARK_M = (-9.0, -6.2)
MEDIAN_HOLE_M = (1.3, 2.3)
# The canvas of each real map ([width, height] m, from the devkit's NuScenesMap docstring).
CANVAS_EDGE_M = {"singapore-onenorth": [1585.6, 2025.0], "singapore-hollandvillage": [2808.3, 2922.9],
                 "singapore-queenstown": [3228.6, 3687.1], "boston-seaport": [2979.5, 2118.1]}
LAYERS = ("polygon", "line", "node", "drivable_area", "road_segment", "road_block", "lane", "ped_crossing", "walkway",
          "stop_line", "carpark_area", "road_divider", "lane_divider", "traffic_light")


def _wrap(angle: np.ndarray | float) -> np.ndarray | float:
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


class _MapWriter:
    """Accumulates the records of one map; tokens from the seeded generator, drawn in creation order."""

    def __init__(self, rng: np.random.Generator, location: str):
        self.rng = rng
        self.map = {"version": VERSION, **{layer: [] for layer in LAYERS},
                    "canvas_edge": CANVAS_EDGE_M.get(location, [3000.0, 3000.0]),
                    "connectivity": {}, "arcline_path_3": {}, "lane_connector": []}
        self._node_of: dict[tuple[float, float], str] = {}

    def token(self) -> str:
        return random_tokens(self.rng, 1)[0]

    def nodes(self, xy: np.ndarray) -> list[str]:
        """Node tokens of the points `xy`: a point already placed (the same x and y) keeps its node, so neighbouring
        polygons and their edge lines share nodes, as in nuScenes' maps (`get_next_roads` follows them)."""
        points = [(float(x), float(y)) for x, y in xy]
        new = list(dict.fromkeys(p for p in points if p not in self._node_of))
        for point, token in zip(new, random_tokens(self.rng, len(new)) if new else []):
            self._node_of[point] = token
            self.map["node"].append({"token": token, "x": point[0], "y": point[1]})
        return [self._node_of[p] for p in points]

    def line(self, xy: np.ndarray) -> tuple[str, list[str]]:
        token, nodes = self.token(), self.nodes(xy)
        self.map["line"].append({"token": token, "node_tokens": nodes})
        return token, nodes

    def polygon(self, exterior: np.ndarray, holes: list[np.ndarray] = ()) -> tuple[str, list[str]]:
        token, nodes = self.token(), self.nodes(exterior)
        self.map["polygon"].append({"token": token, "exterior_node_tokens": nodes,
                                    "holes": [{"node_tokens": self.nodes(h)} for h in holes]})
        return token, nodes

    def record(self, layer: str, **fields) -> str:
        token = self.token()
        self.map[layer].append({"token": token, **fields})
        return token


def _band(road: Road, side: float, s0: float, s1: float, l0: float, l1: float) -> np.ndarray:
    """(P, 2) ring of the strip between lateral offsets l0 and l1 over arc lengths [s0, s1] (not closed)."""
    s = np.linspace(s0, s1, max(2, int(np.ceil((s1 - s0) / EDGE_STEP_M)) + 1))
    right, _ = road.at(s, side * l0)
    left, _ = road.at(s[::-1], side * l1)
    return np.r_[right, left]


def _edge(road: Road, side: float, s0: float, s1: float, lateral: float) -> np.ndarray:
    s = np.linspace(s0, s1, max(2, int(np.ceil((s1 - s0) / EDGE_STEP_M)) + 1))
    return road.at(s, side * lateral)[0]


def _arcline_paths(road: Road, side: float, s0: float, s1: float, lateral: float, direction: int) -> list[dict]:
    """Constant-curvature arcline paths (one per ARC_M) along the lane centre, in the lane's direction."""
    n = max(1, int(round((s1 - s0) / ARC_M)))
    knots = np.linspace(s0, s1, n + 1)
    if direction < 0:
        knots = knots[::-1]
    xy, heading = road.at(knots, side * lateral)
    heading = heading + (np.pi if direction < 0 else 0.0)
    paths = []
    for k in range(n):
        (xa, ya), (xb, yb) = xy[k], xy[k + 1]
        ha = float(_wrap(heading[k]))
        turn = float(_wrap(heading[k + 1] - heading[k]))
        chord = float(np.hypot(xb - xa, yb - ya))
        if abs(turn) < 1e-4:
            shape, radius, lengths = "LSL", 999.0, [0.0, chord, 0.0]
            end = (xa + chord * np.cos(ha), ya + chord * np.sin(ha), ha)
        else:
            radius = chord / (2.0 * np.sin(abs(turn) / 2.0))
            arc = radius * abs(turn)
            shape, lengths = ("LSL" if turn > 0 else "RSR"), [arc / 2, 0.0, arc / 2]
            sign = 1.0 if turn > 0 else -1.0  # the circle's centre is left (+) or right (-) of the start pose
            cx, cy = xa - sign * radius * np.sin(ha), ya + sign * radius * np.cos(ha)
            hb = ha + turn
            end = (cx + sign * radius * np.sin(hb), cy - sign * radius * np.cos(hb), float(_wrap(hb)))
        paths.append({"start_pose": [float(xa), float(ya), ha], "end_pose": [float(v) for v in end],
                      "shape": shape, "radius": float(radius), "segment_length": [float(v) for v in lengths]})
    return paths


def _add_road(w: _MapWriter, road: Road, side: float, with_hole: bool) -> None:
    s_lo, s_hi = float(road.s_m[0]), float(road.s_m[-1])
    n_pieces = max(2, int((s_hi - s_lo) // PIECE_M))
    cuts = np.linspace(s_lo, s_lo + n_pieces * PIECE_M, n_pieces + 1)
    s_mid = float(cuts[n_pieces // 2])

    # Drivable area: two polygons (the road's halves); the first road's first half has a median island.
    hole = []
    if with_hole:
        h0 = float(cuts[1]) + 5.0
        hole = [_band(road, side, h0, h0 + 20.0, *MEDIAN_HOLE_M)[::-1]]  # holes wind the other way
    polygons = [w.polygon(_band(road, side, s_lo, s_mid, *DRIVABLE_M), hole)[0],
                w.polygon(_band(road, side, s_mid, float(cuts[-1]), *DRIVABLE_M))[0]]
    drivable = w.record("drivable_area", polygon_tokens=polygons)

    for lo, hi in WALKWAYS_M:
        w.record("walkway", polygon_token=w.polygon(_band(road, side, s_lo, float(cuts[-1]), lo, hi))[0])
    w.record("road_divider", line_token=w.line(_edge(road, side, s_lo, float(cuts[-1]), ROAD_DIVIDER_M))[0],
             road_segment_token="")  # filled below: the first segment
    road_divider = w.map["road_divider"][-1]
    for lateral in LANE_DIVIDERS_M:
        line_token, nodes = w.line(_edge(road, side, s_lo, float(cuts[-1]), lateral))
        w.record("lane_divider", line_token=line_token,
                 lane_divider_segments=[{"node_token": t, "segment_type": "DOUBLE_DASHED_WHITE"} for t in nodes])

    pieces: list[list[str]] = [[] for _ in LANES_M]
    for i in range(n_pieces):
        s0, s1 = float(cuts[i]), float(cuts[i + 1])
        intersection = i % INTERSECTION_EVERY == INTERSECTION_EVERY - 1
        segment = w.record("road_segment", polygon_token=w.polygon(_band(road, side, s0, s1, *DRIVABLE_M))[0],
                           is_intersection=bool(intersection), drivable_area_token=drivable)
        if i == 0:
            road_divider["road_segment_token"] = segment
        blocks = []
        for lo, hi in ((DRIVABLE_M[0], ROAD_DIVIDER_M), (ROAD_DIVIDER_M, DRIVABLE_M[1])):
            blocks.append(w.record("road_block", polygon_token=w.polygon(_band(road, side, s0, s1, lo, hi))[0],
                                   from_edge_line_token=w.line(_band(road, side, s0, s0, lo, hi)[[0, 2]])[0],
                                   to_edge_line_token=w.line(_band(road, side, s1, s1, lo, hi)[[0, 2]])[0],
                                   road_segment_token=segment))
        for k, (lo, hi, direction) in enumerate(LANES_M):
            polygon, nodes = w.polygon(_band(road, side, s0, s1, lo, hi))
            n_edge = len(nodes) // 2
            if intersection:
                token = w.record("lane_connector", polygon_token=polygon)  # v1.3 connectors: a polygon only
            else:
                right, left = nodes[:n_edge], nodes[n_edge:]
                if direction < 0:
                    right, left = left, right
                token = w.record("lane", polygon_token=polygon, lane_type="CAR",
                                 from_edge_line_token=w.line(_band(road, side, s0, s0, lo, hi)[[0, 2]])[0],
                                 to_edge_line_token=w.line(_band(road, side, s1, s1, lo, hi)[[0, 2]])[0],
                                 left_lane_divider_segments=[{"node_token": t, "segment_type": "DOUBLE_DASHED_WHITE"}
                                                             for t in left],
                                 right_lane_divider_segments=[{"node_token": t, "segment_type": "SINGLE_SOLID_WHITE"}
                                                              for t in right])
            w.map["arcline_path_3"][token] = _arcline_paths(road, side, s0, s1, 0.5 * (lo + hi), direction)
            pieces[k].append(token)
        if intersection:
            crossing = w.record("ped_crossing", polygon_token=w.polygon(_band(road, side, s0, s0 + 4.0, *DRIVABLE_M))[0],
                                road_segment_token=segment)
            light_xy = np.r_[road.at(np.array([s0 - 2.0]), side * (DRIVABLE_M[0] - 0.5))[0],
                             road.at(np.array([s0 - 2.0]), side * (DRIVABLE_M[0] - 0.2))[0]]
            light = w.record("traffic_light", line_token=w.line(light_xy)[0], traffic_light_type="VERTICAL",
                             from_road_block_token=blocks[0],
                             items=[{"color": color, "shape": "CIRCLE",
                                     "rel_pos": {"tx": 0.0, "ty": 0.0, "tz": 0.3 * j, "rx": 0.0, "ry": 0.0, "rz": 0.0},
                                     "to_road_block_tokens": [blocks[0]]} for j, color in enumerate(("RED", "YELLOW", "GREEN"))],
                             pose={"tx": float(light_xy[0, 0]), "ty": float(light_xy[0, 1]), "tz": 2.5,
                                   "rx": 0.0, "ry": 0.0, "rz": 0.0})
            # Stop lines: with-s traffic stops before the crossing at a light, oncoming after it for pedestrians.
            w.record("stop_line", polygon_token=w.polygon(_band(road, side, s0 - 2.0, s0 - 1.0, -5.25, 1.75))[0],
                     stop_line_type="TRAFFIC_LIGHT", ped_crossing_tokens=[], traffic_light_tokens=[light],
                     road_block_token=blocks[0])
            w.record("stop_line", polygon_token=w.polygon(_band(road, side, s0 + 5.0, s0 + 6.0, 1.75, 8.95))[0],
                     stop_line_type="PED_CROSSING", ped_crossing_tokens=[crossing], traffic_light_tokens=[],
                     road_block_token=blocks[1])
        if i == 1:
            w.record("carpark_area", polygon_token=w.polygon(_band(road, side, s0, s1, *CARPARK_M))[0],
                     orientation=float(_wrap(road.at(np.array([s0]))[1][0])), road_block_token=blocks[0])

    for k, (_, _, direction) in enumerate(LANES_M):
        order = pieces[k] if direction > 0 else pieces[k][::-1]
        for j, token in enumerate(order):
            w.map["connectivity"][token] = {"incoming": order[j - 1:j] if j else [],
                                            "outgoing": order[j + 1:j + 2]}


def map_expansion(seed: int, location_index: int, location: str, roads: list[Road], drives_on_right: bool) -> dict:
    """The v1.3 map of one location holding `roads` (the roads of its scenes, in scene order)."""
    w = _MapWriter(np.random.default_rng([seed, 3, location_index]), location)
    side = 1.0 if drives_on_right else -1.0
    for r, road in enumerate(roads):
        _add_road(w, road, side, with_hole=(r == 0))
    return w.map


def write_map_expansions(dataroot: Path, seed: int, roads_by_location: dict[str, list[Road]],
                         drives_on_right: dict[str, bool], locations: list[str]) -> None:
    """`dataroot/maps/expansion/<location>.json` for every location with a road (compact JSON like the real files)."""
    folder = dataroot / "maps" / "expansion"
    folder.mkdir(parents=True, exist_ok=True)
    for index, location in enumerate(locations):
        roads = roads_by_location.get(location, [])
        if roads:
            expansion = map_expansion(seed, index, location, roads, drives_on_right[location])
            (folder / f"{location}.json").write_text(json.dumps(expansion))
