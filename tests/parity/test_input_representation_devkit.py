"""nuparquet.devkit.prediction.input_representation against nuscenes-devkit 1.2.0's
`nuscenes.prediction.input_representation`, on the generator's map set (`map_root`: 6 scenes over two locations,
every scene's road in its location's map, annotations on every keyframe).

The devkit runs its own `NuScenes`, `PredictHelper` and `NuScenesMap` from the JSON; ours runs on
`nuparquet.devkit.NuScenes` over the conversion with a dataroot that holds no JSON at all, so the map comes from the
converted `map/` alone. Rasters are compared whole (`np.array_equal`, shape and dtype uint8): the static layers and
the agents each, and combined, for every instance/sample pair chosen (each track's first annotation, which has no
history; its last; the agents nearest each map's edge, whose window runs off the map) under the defaults and under
other histories, resolutions, windows, layers, colours and colour mappings. The devkit's `load_all_maps` reads the
four nuScenes maps' JSON and this set has two, so its rasterizer is handed its own `NuScenesMap` of those two (the
`devkit_maps` fixture) through that one function.

Also restated: the devkit's prediction tutorial's input building for its MTP and CoverNet baselines
(`nuscenes/prediction/models`: the raster as a (1, 3, H, W) float tensor beside the agent state vector of speed,
acceleration and heading change rate), and the module-level helpers clients import, each against the devkit's.
"""

from __future__ import annotations

from unittest import mock

import numpy as np
import pytest
from pyquaternion import Quaternion

from conftest import SYNTH_VERSION
from nuparquet.devkit.prediction.input_representation import agents as our_agents
from nuparquet.devkit.prediction.input_representation import combinators as our_combinators
from nuparquet.devkit.prediction.input_representation import interface as our_interface
from nuparquet.devkit.prediction.input_representation import static_layers as our_static
from nuparquet.devkit.prediction.input_representation import utils as our_utils
from nuparquet.errors import UsageError


@pytest.fixture(scope="module")
def objects(devkit, map_root, map_out, devkit_maps, tmp_path_factory):
    """(theirs, ours): each a dict with the NuScenes, the PredictHelper and the maps."""
    from nuscenes.prediction import PredictHelper as TheirHelper

    from nuparquet.devkit import NuScenes
    from nuparquet.devkit.prediction import PredictHelper

    theirs_nusc = devkit.NuScenes(SYNTH_VERSION, dataroot=str(map_root), verbose=False)
    no_json = tmp_path_factory.mktemp("dataroot-without-json")  # the JSON deleted after conversion
    ours_nusc = NuScenes(SYNTH_VERSION, dataroot=str(no_json), parquet=map_out, verbose=False)
    theirs = {"nusc": theirs_nusc, "helper": TheirHelper(theirs_nusc), "maps": devkit_maps}
    ours = {"nusc": ours_nusc, "helper": PredictHelper(ours_nusc)}
    return theirs, ours


def their_static(helper, maps, **options):
    """The devkit's StaticLayerRasterizer on `maps` (its `load_all_maps` wants the four nuScenes maps' JSON)."""
    from nuscenes.prediction.input_representation import static_layers

    with mock.patch.object(static_layers, "load_all_maps", lambda helper, verbose=False: maps):
        return static_layers.StaticLayerRasterizer(helper, **options)


def edge_overshoot_m(maps, location: str, xy: np.ndarray) -> np.ndarray:
    """(N,) how far each (N, 2) agent's 80 m square (the default window's) reaches past its map's nodes' bounding
    box, on its farthest side (negative: inside)."""
    nodes = np.array([[n["x"], n["y"]] for n in maps[location].node])
    return np.maximum((nodes.min(0) - (xy - 40)).max(1), ((xy + 40) - nodes.max(0)).max(1))


def chosen_pairs(nusc, maps) -> dict[str, list[tuple[str, str]]]:
    """(instance, sample) pairs: every 14th track's first and last annotation, and per map the two agents whose
    window reaches farthest past its edge."""
    pairs = {"first": [], "last": [], "edge": []}
    for instance in nusc.instance[::14]:
        for kind, end in (("first", "first_annotation_token"), ("last", "last_annotation_token")):
            record = nusc.get("sample_annotation", instance[end])
            pairs[kind].append((record["instance_token"], record["sample_token"]))
    for location in maps:
        records = [a for a in nusc.sample_annotation if location == nusc.get("log", nusc.get(
            "scene", nusc.get("sample", a["sample_token"])["scene_token"])["log_token"])["location"]]
        overshoot = edge_overshoot_m(maps, location, np.array([a["translation"][:2] for a in records]))
        for i in np.argsort(-overshoot, kind="stable")[:2]:
            pairs["edge"].append((records[i]["instance_token"], records[i]["sample_token"]))
    return pairs


def assert_same_image(got: np.ndarray, want: np.ndarray, what) -> None:
    assert got.dtype == want.dtype == np.uint8, what
    assert got.shape == want.shape, what
    assert np.array_equal(got, want), (what, int((got != want).any(-1).sum()), "pixels differ")


def compare_rasters(theirs, ours, pairs, static_options=None, agent_options=None, full_pairs=()):
    """Both sides' static layers, agents and their combination for every pair; `make_input_representation`
    itself for `full_pairs`. Returns how many pixels of the static and agent images were not black."""
    from nuscenes.prediction.input_representation.agents import AgentBoxesWithFadedHistory
    from nuscenes.prediction.input_representation.combinators import Rasterizer
    from nuscenes.prediction.input_representation.interface import InputRepresentation

    static_options, agent_options = static_options or {}, agent_options or {}
    want_input = InputRepresentation(their_static(theirs["helper"], theirs["maps"], **static_options),
                                     AgentBoxesWithFadedHistory(theirs["helper"], **agent_options), Rasterizer())
    got_input = our_interface.InputRepresentation(
        our_static.StaticLayerRasterizer(ours["helper"], **static_options),
        our_agents.AgentBoxesWithFadedHistory(ours["helper"], **agent_options), our_combinators.Rasterizer())
    painted = np.zeros(2, np.int64)
    for instance, sample in pairs:
        parts = []
        sides = ((got_input.static_layer_rasterizer, want_input.static_layer_rasterizer),
                 (got_input.agent_rasterizer, want_input.agent_rasterizer))
        for i, (got_part, want_part) in enumerate(sides):
            want = want_part.make_representation(instance, sample)
            got = got_part.make_representation(instance, sample)
            assert_same_image(got, want, (type(want_part).__name__, instance, sample))
            painted[i] += int(want.any(-1).sum())
            parts.append((got, want))
        assert_same_image(got_input.combinator.combine([g for g, _ in parts]),
                          want_input.combinator.combine([w for _, w in parts]), ("combined", instance, sample))
    for instance, sample in full_pairs:
        assert_same_image(got_input.make_input_representation(instance, sample),
                          want_input.make_input_representation(instance, sample), ("input", instance, sample))
    return painted


def test_default_rasters_of_first_last_and_map_edge_agents(objects):
    theirs, ours = objects
    pairs = chosen_pairs(theirs["nusc"], theirs["maps"])
    # the first annotations have no history, the last ones do
    assert all(theirs["helper"].get_past_for_agent(i, s, 1, False).shape == (0,) for i, s in pairs["first"])
    assert any(len(theirs["helper"].get_past_for_agent(i, s, 1, False)) for i, s in pairs["last"])
    # each edge agent's window runs past its map
    for instance, sample in pairs["edge"]:
        location = theirs["helper"].get_map_name_from_sample_token(sample)
        xy = np.array([theirs["helper"].get_sample_annotation(instance, sample)["translation"][:2]])
        assert edge_overshoot_m(theirs["maps"], location, xy)[0] > 3
    every = pairs["first"] + pairs["last"] + pairs["edge"]
    assert len({s for _, s in every}) > 10 and len(every) > 40
    painted = compare_rasters(theirs, ours, every, agent_options={"seconds_of_history": 1},
                              full_pairs=every[::10])
    assert (painted > 0).all()  # map and agents were drawn, not two black images


@pytest.mark.parametrize("seconds", [0, 0.5, 2, 3.2])
def test_other_histories(objects, seconds):
    theirs, ours = objects
    pairs = chosen_pairs(theirs["nusc"], theirs["maps"])
    compare_rasters(theirs, ours, pairs["last"][::4] + pairs["first"][:2],
                    agent_options={"seconds_of_history": seconds})


@pytest.mark.parametrize("window", [
    {"resolution": 0.25},
    {"resolution": 0.2, "meters_ahead": 30, "meters_behind": 20, "meters_left": 15, "meters_right": 35},
    {"resolution": 0.3, "meters_ahead": 12, "meters_behind": 12, "meters_left": 40, "meters_right": 8},
    {"resolution": 0.15, "meters_ahead": 55.5, "meters_behind": 3, "meters_left": 7.3, "meters_right": 21},
])
def test_other_resolutions_and_windows(objects, window):
    theirs, ours = objects
    pairs = chosen_pairs(theirs["nusc"], theirs["maps"])
    compare_rasters(theirs, ours, pairs["last"][::3] + pairs["edge"], static_options=window,
                    agent_options={"seconds_of_history": 1.5, **window})


def test_custom_layers_colours_and_colour_mapping(objects):
    theirs, ours = objects
    pairs = chosen_pairs(theirs["nusc"], theirs["maps"])
    # every mask layer; (0, 0, 1) is black to OpenCV's grey (not drawn), 300 wraps to 44 in the uint8 cast, and
    # a float colour is truncated; traffic_light gives no mask, so the colours after it move up one layer
    layers = ["drivable_area", "road_segment", "road_block", "lane", "ped_crossing", "walkway", "stop_line",
              "carpark_area", "road_divider", "traffic_light", "lane_divider"]
    colors = [(30, 30, 30), (0, 0, 1), (60, 200, 10), (300, 5, 5), (0.5, 100.7, 250.2), (10, 10, 200),
              (200, 0, 200), (90, 90, 0), (255, 0, 0), (0, 255, 255), (123, 45, 67)]

    def mapping(category_name: str):
        return (0, 200, 100) if "vehicle" in category_name else (20, 20, 20)

    compare_rasters(theirs, ours, pairs["last"][::3] + pairs["edge"][:2],
                    static_options={"layer_names": layers, "colors": colors, "resolution": 0.2},
                    agent_options={"seconds_of_history": 2, "resolution": 0.2, "color_mapping": mapping})
    # fewer colours than layers: the devkit's zip draws only the first ones
    compare_rasters(theirs, ours, pairs["edge"], static_options={"layer_names": ["walkway", "drivable_area",
                                                                               "lane"], "colors": [(9, 99, 199)]})


def test_the_devkits_classes_on_our_helper_and_ours_on_the_devkits_helper_over_our_nuscenes(objects):
    """The devkit's rasterizers run on our PredictHelper (its agents use only the helper; its map layers read the
    JSON, handed over as above), and ours run on the devkit's PredictHelper over our NuScenes."""
    from nuscenes.prediction import PredictHelper as TheirHelper
    from nuscenes.prediction.input_representation.agents import AgentBoxesWithFadedHistory

    theirs, ours = objects
    pairs = chosen_pairs(theirs["nusc"], theirs["maps"])
    pairs = pairs["last"][::5] + pairs["first"][:2]
    on_ours = {"helper": ours["helper"], "maps": theirs["maps"]}
    compare_rasters(on_ours, ours, pairs, agent_options={"seconds_of_history": 1})
    their_helper_on_our_nusc = {"helper": TheirHelper(ours["nusc"])}
    compare_rasters(theirs, their_helper_on_our_nusc, pairs, agent_options={"seconds_of_history": 2})
    instance, sample = pairs[0]
    assert_same_image(AgentBoxesWithFadedHistory(ours["helper"]).make_representation(instance, sample),
                      AgentBoxesWithFadedHistory(theirs["helper"]).make_representation(instance, sample), "agents")


def tutorial_inputs(helper, static_rasterizer, instance_token_img: str, sample_token_img: str):
    """The devkit's prediction tutorial, building the MTP / CoverNet inputs (torch.Tensor is float32; the models
    take the image as (batch, 3, H, W) and the agent state vector as (batch, 3))."""
    from_module = type(static_rasterizer).__module__.rsplit(".", 1)[0]
    import importlib

    agents = importlib.import_module(from_module + ".agents")
    combinators = importlib.import_module(from_module + ".combinators")
    interface = importlib.import_module(from_module + ".interface")
    agent_rasterizer = agents.AgentBoxesWithFadedHistory(helper, seconds_of_history=1)
    mtp_input_representation = interface.InputRepresentation(static_rasterizer, agent_rasterizer,
                                                             combinators.Rasterizer())
    img = mtp_input_representation.make_input_representation(instance_token_img, sample_token_img)
    agent_state_vector = np.array([[helper.get_velocity_for_agent(instance_token_img, sample_token_img),
                                    helper.get_acceleration_for_agent(instance_token_img, sample_token_img),
                                    helper.get_heading_change_rate_for_agent(instance_token_img, sample_token_img)]],
                                  dtype=np.float32)
    image_tensor = np.asarray(img, dtype=np.float32).transpose(2, 0, 1)[None]  # torch.Tensor(img).permute(2, 0, 1)
    return image_tensor, agent_state_vector


def test_the_devkits_prediction_tutorial_inputs_for_its_baselines(objects):
    theirs, ours = objects
    pairs = chosen_pairs(theirs["nusc"], theirs["maps"])
    their_rasterizer = their_static(theirs["helper"], theirs["maps"])
    our_rasterizer = our_static.StaticLayerRasterizer(ours["helper"])
    states = []
    for instance, sample in pairs["last"][:4] + pairs["first"][:1]:
        want_image, want_state = tutorial_inputs(theirs["helper"], their_rasterizer, instance, sample)
        got_image, got_state = tutorial_inputs(ours["helper"], our_rasterizer, instance, sample)
        assert want_image.shape == (1, 3, 500, 500) and got_image.dtype == want_image.dtype
        assert np.array_equal(got_image, want_image)
        assert np.array_equal(got_state, want_state, equal_nan=True)
        states.append(want_state)
    assert np.isnan(states[-1]).all() and not np.isnan(states[0]).any()  # a first annotation has no rates


def test_load_all_maps_serves_the_converted_maps_without_json(objects):
    theirs, ours = objects
    maps = our_static.load_all_maps(ours["helper"])
    assert list(maps) == sorted(theirs["maps"])
    for location in theirs["maps"]:
        assert maps[location] is ours["nusc"]._dataset.map(location)  # the dataset's, read once
        assert maps[location].location == location


def test_load_all_maps_names_an_output_without_maps(map_root, tmp_path):
    from nuparquet.conversion import convert
    from nuparquet.devkit import NuScenes
    from nuparquet.devkit.prediction import PredictHelper

    out = tmp_path / "out"
    convert(map_root, SYNTH_VERSION, out, no_map=True)
    helper = PredictHelper(NuScenes(SYNTH_VERSION, dataroot=str(tmp_path), parquet=out, verbose=False))
    with pytest.raises(UsageError, match=r"has no map/ datasets: convert a dataroot holding maps/expansion"):
        our_static.StaticLayerRasterizer(helper)


# --- the module-level helpers, one by one ---------------------------------------------------------------------


def test_pixel_coordinates_crops_and_rotation_matrices():
    from nuscenes.prediction.input_representation import utils as their_utils

    rng = np.random.default_rng(3)
    for _ in range(300):
        location = tuple(rng.uniform(-60, 60, 2) + [400.0, 1200.0])
        center = (400.0 + rng.uniform(-1, 1), 1200.0 + rng.uniform(-1, 1))
        pixels = tuple(rng.integers(0, 900, 2) + rng.choice([0, 0.5], 2))
        resolution = float(rng.choice([0.1, 0.15, 0.25, 1 / 3]))
        want = their_utils.convert_to_pixel_coords(location, center, pixels, resolution)
        got = our_utils.convert_to_pixel_coords(location, center, pixels, resolution)
        assert got == want and all(type(v) is int for v in got)
    # truncation toward zero, not floor: a point just left of and above pixel 0
    assert our_utils.convert_to_pixel_coords((-0.05, 0.05), (0, 0), (0, 0), 0.1) == (0, 0)
    for window in [(40, 10, 25, 25, 0.1, 800), (30, 20, 15, 35, 0.2, 350), (55.5, 3, 7.3, 21, 0.15, 740)]:
        assert our_utils.get_crops(*window) == their_utils.get_crops(*window)
    for yaw in (-np.pi, -2.0, -0.3, 0.0, 0.7, np.pi / 2, 3.1):
        for shape in ((800, 800, 3), (500, 700, 3)):
            assert np.array_equal(our_utils.get_rotation_matrix(shape, yaw),
                                  their_utils.get_rotation_matrix(shape, yaw))


def test_rotate_and_crop_is_the_full_warp_cropped():
    import cv2

    rng = np.random.default_rng(8)
    for side in (400, 333, 800):
        image = np.zeros((side, side, 3))
        for _ in range(40):
            corners = rng.integers(0, side, (4, 2)).astype(np.int32)
            cv2.fillPoly(image, [corners], tuple(rng.uniform(0, 255, 3).tolist()))
        for yaw in rng.uniform(-np.pi, np.pi, 4):
            full = cv2.warpAffine(image, our_utils.get_rotation_matrix(image.shape, yaw), (side, side))
            for crop in [(slice(0, side // 2), slice(side // 4, side - 3)), (slice(0, side), slice(0, side)),
                         (slice(0, 0), slice(0, side)), (slice(0, side + 5), slice(-3, side))]:
                got = our_utils.rotate_and_crop(image, yaw, *crop)
                assert np.array_equal(got, full[crop].astype("uint8")) and got.shape == full[crop].shape


def test_static_layer_helpers(objects):
    from nuscenes.prediction.input_representation import static_layers as theirs_module

    theirs, ours = objects
    assert our_static.get_patchbox(1.5, -2.0, 80) == theirs_module.get_patchbox(1.5, -2.0, 80)
    for yaw in (-np.pi, -1.0, -0.0, 0.0, 1e-9, 2.0, np.pi):
        assert our_static.correct_yaw(yaw) == theirs_module.correct_yaw(yaw)
    mask = np.repeat(np.random.default_rng(1).integers(0, 2, (50, 60, 1)).astype(np.uint8), 3, 2)
    for color in [(255, 255, 255), (300, 5.9, 0), (0.5, 100.7, 250.2)]:
        got = our_static.change_color_of_binary_mask(mask, color)
        want = theirs_module.change_color_of_binary_mask(mask, color)
        assert np.array_equal(got, want) and got.dtype == want.dtype
        assert np.array_equal(our_static._colored_mask(mask[..., 0], color), want)
    yaws = np.linspace(-np.pi, np.pi, 721)
    for agent_yaw in (-np.pi, -2.5, 0.0, 0.4, np.pi):
        for lane_yaw in yaws:
            want = theirs_module.color_by_yaw(np.float64(agent_yaw), float(lane_yaw))
            assert our_static.color_by_yaw(np.float64(agent_yaw), float(lane_yaw)) == want
    for location, nusc_map in theirs["maps"].items():
        layers = ours["nusc"]._dataset.map(location)
        for node in nusc_map.node[::40]:
            for radius, resolution in ((50, 1), (12.5, 0.5)):
                want = theirs_module.get_lanes_in_radius(node["x"], node["y"], radius, resolution, nusc_map)
                got = our_static.get_lanes_in_radius(node["x"], node["y"], radius, resolution, layers)
                assert list(got) == list(want) and got == want
        node = nusc_map.node[len(nusc_map.node) // 2]
        for yaw in (-2.0, 0.3):
            want = theirs_module.draw_lanes_in_agent_frame(400, node["x"], node["y"], yaw, 30, 0.2, 1, nusc_map)
            got = our_static.draw_lanes_in_agent_frame(400, node["x"], node["y"], yaw, 30, 0.2, 1, layers)
            assert_same_image(got, want, "draw_lanes_in_agent_frame")
            assert want.any()
        # no lane within the radius: nothing drawn, no error
        far = (node["x"] + 1e4, node["y"])
        want = theirs_module.draw_lanes_in_agent_frame(200, *far, 0.3, 30, 0.2, 1, nusc_map)
        assert_same_image(our_static.draw_lanes_in_agent_frame(200, *far, 0.3, 30, 0.2, 1, layers), want, "no lanes")
        assert not want.any()
        # a colour function of the client's own, called with the devkit's arguments
        lanes = theirs_module.get_lanes_in_radius(node["x"], node["y"], 30, 1, nusc_map)

        def stripes(agent_yaw, lane_yaw):
            return (100.0, 50.0 + 100 * (lane_yaw > agent_yaw), 7)

        want = theirs_module.draw_lanes_on_image(np.zeros((300, 300, 3)), lanes, (node["x"], node["y"]), 0.5,
                                                 (150, 140), 0.25, stripes)
        got = our_static.draw_lanes_on_image(np.zeros((300, 300, 3)), lanes, (node["x"], node["y"]), 0.5,
                                             (150, 140), 0.25, stripes)
        assert np.array_equal(got, want) and want.any()


def test_a_lane_without_an_arcline_path_is_named(objects):
    """The devkit's `discretize_lanes` raises KeyError for such a lane; ours names it."""
    from nuparquet.map.queries import MapLayers

    theirs, ours = objects
    location, nusc_map = next(iter(theirs["maps"].items()))
    layers = MapLayers.open(ours["nusc"]._dataset, location)  # a copy of its own, altered below
    lane = nusc_map.lane[len(nusc_map.lane) // 2]
    del layers.arcline_path_3[lane["token"]]
    centerlines = our_static.LaneCenterlines(layers, 1)
    node = nusc_map.get("node", nusc_map.get("polygon", lane["polygon_token"])["exterior_node_tokens"][0])
    with pytest.raises(UsageError, match=f"no lane or lane connector '{lane['token']}' in the map of {location}"):
        centerlines.in_radius(node["x"], node["y"], 5)
    far = our_static.LaneCenterlines(layers, 1).in_radius(node["x"] + 1e5, node["y"], 5)
    assert far == {}


def test_agent_helpers(objects):
    from nuscenes.prediction.input_representation import agents as theirs_module

    theirs, _ = objects
    nusc = theirs["nusc"]
    records = nusc.sample_annotation[::11]
    center = records[0]
    for record in records:
        for resolution, pixels in ((0.1, (400.0, 400.0)), (0.25, (151.5, 80.0))):
            want = theirs_module.get_track_box(record, center["translation"][:2], pixels, resolution)
            got = our_agents.get_track_box(record, center["translation"][:2], pixels, resolution)
            assert got.dtype == want.dtype and np.array_equal(got, want)
    assert np.array_equal(our_agents.pixels_to_box_corners(10, 20, 30.5, 12.25, 0.3),
                          theirs_module.pixels_to_box_corners(10, 20, 30.5, 12.25, 0.3))
    with pytest.raises(AssertionError):
        our_agents.get_track_box(center, (0, 0), (0, 0), 0)
    for color in [(255, 0, 0), (255, 255, 0), (204, 0, 204), (255, 153, 51), (10, 20, 30)]:
        for total in (1, 2, 4):
            for step in range(total + 1):
                assert our_agents.fade_color(color, step, total) == theirs_module.fade_color(color, step, total)
    for name in ("vehicle.car", "movable_object.barrier", "human.pedestrian.adult", "animal"):
        assert our_agents.default_colors(name) == theirs_module.default_colors(name)
    with pytest.raises(ValueError, match="Cannot map static.manmade to a color."):
        our_agents.default_colors("static.manmade")
    sample = center["sample_token"]
    history = theirs["helper"].get_past_for_sample(sample, 2, in_agent_frame=False, just_xy=False)
    present = theirs["helper"].get_annotations_for_sample(sample)
    want = theirs_module.add_present_time_to_history(present, theirs_module.reverse_history(history))
    got = our_agents.add_present_time_to_history(present, our_agents.reverse_history(history))
    assert got == want and list(got) == list(want)
    assert our_agents.add_present_time_to_history(present[:1], {}) == {present[0]["instance_token"]: present[:1]}
    for get_color in (theirs_module.default_colors, lambda name: (5, 250, 90)):
        want_image, got_image = np.zeros((600, 600, 3)), np.zeros((600, 600, 3))
        theirs_module.draw_agent_boxes(present[2], (300.0, 300.0), want, want_image, get_color, 0.2)
        our_agents.draw_agent_boxes(present[2], (300.0, 300.0), got, got_image, get_color, 0.2)
        assert np.array_equal(got_image, want_image) and want_image.any()
    with pytest.raises(ValueError, match="Resolution must be positive. Received 0."):
        our_agents.AgentBoxesWithFadedHistory(None, resolution=0)
    assert Quaternion(center["rotation"])  # the records carry the devkit's fields


def test_the_combinator(objects):
    from nuscenes.prediction.input_representation import combinators as theirs_module

    rng = np.random.default_rng(5)
    images = [rng.integers(0, 3, (40, 30, 3)).astype(np.uint8) * rng.integers(0, 120, 3).astype(np.uint8)
              for _ in range(4)]
    images[1][:5] = (0, 0, 1)  # grey 0: not foreground
    got, want = our_combinators.Rasterizer().combine(images), theirs_module.Rasterizer().combine(images)
    assert np.array_equal(got, want) and got.dtype == want.dtype
    assert (got[:5] != (0, 0, 1)).any(-1).all()
    with pytest.raises(ValueError, match=r"must have the same shape. Received \(40, 30, 3\) and \(4, 30, 3\)"):
        our_combinators.add_foreground_to_image(images[0], images[1][:4])
    with pytest.raises(ValueError, match="must be of type 'uint8'. Received uint8 and float64"):
        our_combinators.add_foreground_to_image(images[0], images[1].astype(np.float64))
