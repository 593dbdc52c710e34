"""`NuScenesMap`: the devkit's map API (`nuscenes.map_expansion.map_api`), served from a nuparquet output.

```python
from nuparquet.devkit.map_expansion.map_api import NuScenesMap, NuScenesMapExplorer  # instead of nuscenes.map_...
nusc_map = NuScenesMap(dataroot="/data/nusc.parquet", map_name="singapore-onenorth")
```

Construction reads the manifest only. Each layer's record list (`nusc_map.lane`, `getattr(nusc_map, layer)`, the
`arcline_path_3` and `connectivity` dicts) is rebuilt on first access from `map/<layer>` (`sources.map_records`:
the records `json.load` gave, field for field, with the devkit's shortcuts added: `exterior_node_tokens` / `holes`
on polygon records, `node_tokens` on line records, stop lines' `cue`, lanes' divider segment nodes), and so is
each layer's part of `_token2ind`: the map JSON files may be gone.

The spatial queries are answered by `nuparquet.map.queries.MapLayers` (`Dataset.map(map_name)`: the stored shapely
geometry and its trees): `layers_on_point`, `record_on_point`, `get_records_in_patch`, `get_records_in_radius`,
`get_closest_lane`, `get_bounds`, `get_next_roads`, `get_map_mask`, `discretize_lanes`, `discretize_centerlines`.
The rest is the devkit's code over the rebuilt records (`get`, `getind`, the lane graph, `get_arcline_path`) and
the explorer's (`map_explorer`, `map_renders`), with the devkit's types, order and errors.

Longer than our ~300-line norm on purpose: it mirrors the devkit's class, whose every method clients call by name.
"""

from __future__ import annotations

import os
from typing import Dict, List, Optional, Tuple, Union

import numpy as np

# the output's reader loads with the module, as the devkit's map_api loads its libraries on import: construction
# itself reads the manifest only
import nuparquet.dataset.core  # noqa: F401
from nuparquet.devkit.map_expansion.map_explorer import Geometry, NuScenesMapExplorer
from nuparquet.devkit.output import open_output
from nuparquet.errors import UsageError
from nuparquet.sources.map_records import layer_records, map_entries

__all__ = ["NuScenesMap", "NuScenesMapExplorer", "Geometry", "locations"]

locations = ['singapore-onenorth', 'singapore-hollandvillage', 'singapore-queenstown', 'boston-seaport']

GEOMETRIC_LAYERS = ['polygon', 'line', 'node']
NON_GEOMETRIC_POLYGON_LAYERS = ['drivable_area', 'road_segment', 'road_block', 'lane', 'ped_crossing', 'walkway',
                                'stop_line', 'carpark_area']
NON_GEOMETRIC_LINE_LAYERS = ['road_divider', 'lane_divider', 'traffic_light']
LAYER_NAMES = GEOMETRIC_LAYERS + NON_GEOMETRIC_POLYGON_LAYERS + ['lane_connector'] + NON_GEOMETRIC_LINE_LAYERS
LAZY = frozenset(LAYER_NAMES + ['arcline_path_3', 'connectivity'])


class _TokenIndex(dict):
    """The devkit's `_token2ind` ({layer: {token: index}}), each layer's built when first asked for; iterating,
    comparing or printing it builds the rest first (in the devkit's layer order)."""

    def __init__(self, nusc_map: NuScenesMap) -> None:
        super().__init__()
        self._map = nusc_map

    def __missing__(self, layer_name: str) -> dict:
        if layer_name not in LAYER_NAMES:
            raise KeyError(layer_name)
        index = {member['token']: ind for ind, member in enumerate(getattr(self._map, layer_name))}
        dict.__setitem__(self, layer_name, index)
        return index

    def _complete(self) -> None:
        if list(dict.keys(self))[:len(LAYER_NAMES)] == LAYER_NAMES:
            return
        built = dict(dict.items(self))
        dict.clear(self)
        for layer_name in LAYER_NAMES:
            if layer_name in built:
                dict.__setitem__(self, layer_name, built.pop(layer_name))
            else:
                self.__missing__(layer_name)
        for key, value in built.items():  # keys a caller added
            dict.__setitem__(self, key, value)

    def get(self, key, default=None):
        return self[key] if key in self else default

    def __contains__(self, key) -> bool:
        return key in LAYER_NAMES or dict.__contains__(self, key)

    def __iter__(self):
        self._complete()
        return dict.__iter__(self)

    def __len__(self) -> int:
        self._complete()
        return dict.__len__(self)

    def keys(self):
        self._complete()
        return dict.keys(self)

    def values(self):
        self._complete()
        return dict.values(self)

    def items(self):
        self._complete()
        return dict.items(self)

    def copy(self) -> dict:
        self._complete()
        return dict(dict.items(self))

    def __eq__(self, other) -> bool:
        self._complete()
        return dict.__eq__(self, other)

    __hash__ = None

    def __repr__(self) -> str:
        self._complete()
        return dict.__repr__(self)

    def __reduce__(self):
        return dict, (self.copy(),)


class NuScenesMap:
    """The devkit's `NuScenesMap` over a converted nuparquet directory.

    Args:
        dataroot: the converted directory (`nuparquet convert`'s OUT), or, with `parquet`, the dataroot it was
            converted from (where the devkit would read `maps/expansion/<map_name>.json`: `json_fname`, and the
            bitmaps `BitMap` reads).
        map_name: one of the devkit's four `locations`; the output must hold its map.
        parquet: the output directory of `nuparquet convert`; may be omitted when `dataroot` is one.
        storage_options: polars' object-store options for a `parquet` URL.
    """

    def __init__(self, dataroot: str = '/data/sets/nuscenes', map_name: str = 'singapore-onenorth', *,
                 parquet: str | os.PathLike | None = None, storage_options: dict | None = None):
        assert map_name in locations, 'Error: Unknown map name %s!' % map_name
        dataset, given = open_output(dataroot, parquet, what="nuparquet.devkit.map_expansion.map_api.NuScenesMap",
                                     convert="nuparquet convert {dataroot} --version VERSION --out OUT",
                                     storage_options=storage_options)
        entries = map_entries(dataset.manifest)
        if map_name not in entries:
            raise UsageError(f"{dataset.root} holds no map of {map_name!r} (maps: {', '.join(entries) or 'none'}): "
                             "convert a dataroot whose maps/expansion/ holds it")
        self._arguments = (dataroot, map_name, parquet, storage_options)
        self._dataset = dataset
        self._entry = entries[map_name]
        self.parquet = dataset.root
        self.dataroot = str(given) if given is not None else (dataset.dataroot or str(dataset.root))
        self.map_name = map_name

        self.geometric_layers = list(GEOMETRIC_LAYERS)
        self.non_geometric_polygon_layers = list(NON_GEOMETRIC_POLYGON_LAYERS)
        self.lookup_polygon_layers = self.non_geometric_polygon_layers + ['lane_connector']
        self.non_geometric_line_layers = list(NON_GEOMETRIC_LINE_LAYERS)
        self.non_geometric_layers = self.non_geometric_polygon_layers + self.non_geometric_line_layers
        self.layer_names = self.geometric_layers + self.lookup_polygon_layers + self.non_geometric_line_layers

        self.json_fname = os.path.join(self.dataroot, 'maps', 'expansion', '{}.json'.format(self.map_name))
        scalars = self._entry["scalars"]
        self.version = scalars['version'] if 'version' in scalars else '1.0'
        if self.version < '1.3':
            raise Exception('Error: You are using an outdated map version (%s)! '
                            'Please go to https://www.nuscenes.org/download to download the latest map!')
        self.canvas_edge = scalars['canvas_edge']
        self.explorer = NuScenesMapExplorer(self)

    def __repr__(self) -> str:
        return f"<nuparquet.devkit NuScenesMap {self.map_name} parquet={str(self.parquet)!r}>"

    def __reduce__(self):
        """Pickled as its arguments (e.g. for a data loader's worker processes): the copy opens the same output and
        rebuilds its records on demand. Changes made to records are not carried over."""
        return _reopen, self._arguments

    # --- the layers, rebuilt on first access -------------------------------------------------------------------

    def __getattr__(self, name: str):
        # only called for attributes not set yet: the layers and indexes built on first use
        if name.startswith('__') or '_entry' not in self.__dict__:
            raise AttributeError(name)
        if name in LAZY:
            records = layer_records(self._dataset, self._entry, name)
            self.__dict__[name] = records
            self._make_shortcuts(name, records)
            return records
        if name == '_token2ind':
            self.__dict__[name] = _TokenIndex(self)
            return self.__dict__[name]
        if name == 'json_obj':  # the file as the devkit holds it: the same (decorated) record objects
            scalars = self._entry["scalars"]
            self.__dict__[name] = {key: scalars[key] if key in scalars else getattr(self, key)
                                   for key in self._entry["top_keys"]}
            return self.__dict__[name]
        if name == '_map_layers':  # the vectorised queries over the stored geometry
            self.__dict__[name] = self._dataset.map(self.map_name)
            return self.__dict__[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _make_token2ind(self) -> None:
        """A fresh `_token2ind`, built again on first use from the layers as they are now (the devkit's
        `map_expansion.utils.drop_disconnected_lanes` calls it after removing records)."""
        self.__dict__['_token2ind'] = _TokenIndex(self)

    def _make_shortcuts(self, layer_name: str, records) -> None:
        """The devkit's `_make_shortcuts` for one layer (the records it links to are built first, so the shortcuts
        share their objects, as the devkit's do)."""
        if layer_name in self.non_geometric_polygon_layers and layer_name != 'drivable_area':
            for record in records:
                polygon_obj = self.get('polygon', record['polygon_token'])
                record['exterior_node_tokens'] = polygon_obj['exterior_node_tokens']
                record['holes'] = polygon_obj['holes']
        if layer_name in self.non_geometric_line_layers:
            for record in records:
                record['node_tokens'] = self.get('line', record['line_token'])['node_tokens']
        if layer_name == 'stop_line':
            for record in records:
                record['cue'] = self._get_stop_line_cue(record)
        if layer_name == 'lane':  # self.get('node', ...) for each segment, its lookups hoisted (thousands of lanes)
            nodes, node_index = self.node, self._token2ind['node']
            for record in records:
                record['left_lane_divider_segment_nodes'] = [nodes[node_index[segment['node_token']]] for segment in
                                                             record['left_lane_divider_segments']]
                record['right_lane_divider_segment_nodes'] = [nodes[node_index[segment['node_token']]] for segment in
                                                              record['right_lane_divider_segments']]

    def _get_stop_line_cue(self, stop_line_record: dict) -> List[dict]:
        if stop_line_record['stop_line_type'] in ['PED_CROSSING', 'TURN_STOP']:
            return [self.get('ped_crossing', token) for token in stop_line_record['ped_crossing_tokens']]
        elif stop_line_record['stop_line_type'] in ['STOP_SIGN', 'YIELD']:
            return []
        elif stop_line_record['stop_line_type'] == 'TRAFFIC_LIGHT':
            return [self.get('traffic_light', token) for token in stop_line_record['traffic_light_tokens']]

    def get(self, layer_name: str, token: str) -> dict:
        """The record of `token` in `layer_name` (the same dict on every call)."""
        assert layer_name in self.layer_names, "Layer {} not found".format(layer_name)

        return getattr(self, layer_name)[self.getind(layer_name, token)]

    def getind(self, layer_name: str, token: str) -> int:
        """The index of the record in its layer's list."""
        return self._token2ind[layer_name][token]

    # --- the explorer's calls --------------------------------------------------------------------------------

    def render_record(self, layer_name: str, token: str, alpha: float = 0.5, figsize: Tuple[float, float] = None,
                      other_layers: List[str] = None, bitmap=None):
        return self.explorer.render_record(layer_name, token, alpha,
                                           figsize=figsize, other_layers=other_layers, bitmap=bitmap)

    def render_layers(self, layer_names: List[str], alpha: float = 0.5,
                      figsize: Union[None, float, Tuple[float, float]] = None, tokens: List[str] = None, bitmap=None):
        return self.explorer.render_layers(layer_names, alpha, figsize=figsize, tokens=tokens, bitmap=bitmap)

    def render_map_patch(self, box_coords: Tuple[float, float, float, float], layer_names: List[str] = None,
                         alpha: float = 0.5, figsize: Tuple[int, int] = (15, 15), render_egoposes_range: bool = True,
                         render_legend: bool = True, bitmap=None):
        return self.explorer.render_map_patch(box_coords, layer_names=layer_names, alpha=alpha, figsize=figsize,
                                              render_egoposes_range=render_egoposes_range,
                                              render_legend=render_legend, bitmap=bitmap)

    def render_map_in_image(self, nusc, sample_token: str, camera_channel: str = 'CAM_FRONT', alpha: float = 0.3,
                            patch_radius: float = 10000, min_polygon_area: float = 1000,
                            render_behind_cam: bool = True, render_outside_im: bool = True,
                            layer_names: List[str] = None, verbose: bool = True, out_path: str = None):
        return self.explorer.render_map_in_image(
            nusc, sample_token, camera_channel=camera_channel, alpha=alpha,
            patch_radius=patch_radius, min_polygon_area=min_polygon_area,
            render_behind_cam=render_behind_cam, render_outside_im=render_outside_im,
            layer_names=layer_names, verbose=verbose, out_path=out_path)

    def render_egoposes_on_fancy_map(self, nusc, scene_tokens: List = None, verbose: bool = True,
                                     out_path: str = None, render_egoposes: bool = True,
                                     render_egoposes_range: bool = True, render_legend: bool = True, bitmap=None):
        return self.explorer.render_egoposes_on_fancy_map(nusc, scene_tokens=scene_tokens,
                                                          verbose=verbose, out_path=out_path,
                                                          render_egoposes=render_egoposes,
                                                          render_egoposes_range=render_egoposes_range,
                                                          render_legend=render_legend, bitmap=bitmap)

    def render_centerlines(self, resolution_meters: float = 0.5,
                           figsize: Union[None, float, Tuple[float, float]] = None, bitmap=None):
        return self.explorer.render_centerlines(resolution_meters=resolution_meters, figsize=figsize, bitmap=bitmap)

    def render_map_mask(self, patch_box: Tuple[float, float, float, float], patch_angle: float,
                        layer_names: List[str] = None, canvas_size: Tuple[int, int] = (100, 100),
                        figsize: Tuple[int, int] = (15, 15), n_row: int = 2):
        return self.explorer.render_map_mask(patch_box, patch_angle, layer_names=layer_names,
                                             canvas_size=canvas_size, figsize=figsize, n_row=n_row)

    def get_map_mask(self, patch_box: Optional[Tuple[float, float, float, float]], patch_angle: float,
                     layer_names: List[str] = None,
                     canvas_size: Optional[Tuple[int, int]] = (100, 100)) -> np.ndarray:
        return self.explorer.get_map_mask(patch_box, patch_angle, layer_names=layer_names, canvas_size=canvas_size)

    def get_map_geom(self, patch_box: Tuple[float, float, float, float], patch_angle: float,
                     layer_names: List[str]) -> List[Tuple[str, List[Geometry]]]:
        return self.explorer.get_map_geom(patch_box, patch_angle, layer_names)

    def get_records_in_patch(self, box_coords: Tuple[float, float, float, float], layer_names: List[str] = None,
                             mode: str = 'intersect') -> Dict[str, List[str]]:
        return self.explorer.get_records_in_patch(box_coords, layer_names=layer_names, mode=mode)

    def is_record_in_patch(self, layer_name: str, token: str, box_coords: Tuple[float, float, float, float],
                           mode: str = 'intersect') -> bool:
        return self.explorer.is_record_in_patch(layer_name, token, box_coords, mode=mode)

    def layers_on_point(self, x: float, y: float, layer_names: List[str] = None) -> Dict[str, str]:
        return self.explorer.layers_on_point(x, y, layer_names=layer_names)

    def record_on_point(self, x: float, y: float, layer_name: str) -> str:
        return self.explorer.record_on_point(x, y, layer_name)

    def extract_polygon(self, polygon_token: str):
        return self.explorer.extract_polygon(polygon_token)

    def extract_line(self, line_token: str):
        return self.explorer.extract_line(line_token)

    def get_bounds(self, layer_name: str, token: str) -> Tuple[float, float, float, float]:
        return self.explorer.get_bounds(layer_name, token)

    def get_records_in_radius(self, x: float, y: float, radius: float,
                              layer_names: List[str], mode: str = 'intersect') -> Dict[str, List[str]]:
        """The records intersecting (or within) the square of half-side `radius` around (x, y)."""
        patch = (x - radius, y - radius, x + radius, y + radius)
        return self.explorer.get_records_in_patch(patch, layer_names, mode=mode)

    # --- lanes -----------------------------------------------------------------------------------------------

    def discretize_centerlines(self, resolution_meters: float) -> List[np.array]:
        """Each lane's then each lane connector's poses (x, y, yaw) at `resolution_meters` (`MapLayers.centerlines`),
        one array per record; a record without arcline paths gets the devkit's `np.array([])`."""
        poses, counts = self._map_layers.centerlines(resolution_meters)
        starts = np.r_[0, np.cumsum(counts)]
        return [poses[starts[i]:starts[i + 1]].copy() if counts[i] else np.array([]) for i in range(len(counts))]

    def discretize_lanes(self, tokens: List[str],
                         resolution_meters: float) -> Dict[str, List[Tuple[float, float, float]]]:
        """{token: the lane's poses (x, y, yaw)}; a token without arcline paths gets [] (the devkit's)."""
        from nuparquet.map.centerlines import discretize_lanes

        tokens = list(tokens)
        poses, counts = discretize_lanes([self.arcline_path_3.get(t, []) for t in tokens], resolution_meters)
        starts = np.r_[0, np.cumsum(counts)]
        return {ID: [tuple(p) for p in poses[starts[i]:starts[i + 1]].tolist()] for i, ID in enumerate(tokens)}

    def _get_connected_lanes(self, lane_token: str, incoming_outgoing: str) -> List[str]:
        if lane_token not in self.connectivity:
            raise ValueError(f"{lane_token} is not a valid lane.")

        return self.connectivity[lane_token][incoming_outgoing]

    def get_outgoing_lane_ids(self, lane_token: str) -> List[str]:
        """The lanes that start where this one ends (the record's own list, as the devkit returns it)."""
        return self._get_connected_lanes(lane_token, 'outgoing')

    def get_incoming_lane_ids(self, lane_token: str) -> List[str]:
        """The lanes that end where this one starts."""
        return self._get_connected_lanes(lane_token, 'incoming')

    def get_arcline_path(self, lane_token: str) -> List[dict]:
        """The lane's arcline paths; ValueError for a lane without any."""
        arcline_path = self.arcline_path_3.get(lane_token)
        if not arcline_path:
            raise ValueError(f'Error: Lane with token {lane_token} does not have a valid arcline path!')

        return arcline_path

    def get_closest_lane(self, x: float, y: float, radius: float = 5) -> str:
        """The lane or lane connector whose 0.5 m centreline pose is nearest (x, y), among those intersecting the
        square of half-side `radius`; '' where none (`MapLayers.closest_lane`)."""
        return str(self._map_layers.closest_lane(x, y, radius_m=radius)[0])

    def render_next_roads(self, x: float, y: float, alpha: float = 0.5,
                          figsize: Union[None, float, Tuple[float, float]] = None, bitmap=None):
        return self.explorer.render_next_roads(x, y, alpha, figsize=figsize, bitmap=bitmap)

    def get_next_roads(self, x: float, y: float) -> Dict[str, List[str]]:
        """The road segments, road blocks and lanes that may follow the finest road at (x, y)
        (`MapLayers.next_roads`); the devkit's AssertionError where no road holds the point."""
        layers = self._map_layers
        on_point = layers.layers_on_point(x, y, ('road_segment', 'road_block', 'lane'))
        assert any(tokens[0] != '' for tokens in on_point.values()), \
            'Error: No suitable layer in the specified point location!'
        return layers.next_roads(x, y)


def _reopen(dataroot, map_name, parquet, storage_options) -> NuScenesMap:
    return NuScenesMap(dataroot, map_name, parquet=parquet, storage_options=storage_options)

