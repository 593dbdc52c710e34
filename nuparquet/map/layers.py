"""The layers of a nuScenes map expansion file, named once (the reader, the converter, the queries and the
renderers all take them from here). The devkit's names for the same groups are given beside each."""

GEOMETRIC_LAYERS = ("node", "line", "polygon")  # devkit geometric_layers
# devkit non_geometric_polygon_layers: the polygon layers `layers_on_point`, `get_records_in_patch` and
# `get_map_mask` walk
POLYGON_LAYERS = ("drivable_area", "road_segment", "road_block", "lane", "ped_crossing", "walkway", "stop_line",
                  "carpark_area")
LINE_LAYERS = ("road_divider", "lane_divider", "traffic_light")  # devkit non_geometric_line_layers
NON_GEOMETRIC_LAYERS = POLYGON_LAYERS + LINE_LAYERS  # devkit non_geometric_layers
LANE_LAYERS = ("lane", "lane_connector")  # what `get_closest_lane` and the centrelines cover
LOOKUP_POLYGON_LAYERS = POLYGON_LAYERS + ("lane_connector",)  # devkit lookup_polygon_layers
LIST_LAYERS = GEOMETRIC_LAYERS + LOOKUP_POLYGON_LAYERS + LINE_LAYERS  # a JSON array of records each
DICT_LAYERS = ("arcline_path_3", "connectivity")  # a JSON object keyed by lane token
