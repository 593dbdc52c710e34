"""Six map clients nobody here wrote (HDMapNet, MapTR v2, StreamMapNet, bevfusion, trajdata, PGP; restated in
`map_clients.py`) give the same output on the devkit's `NuScenesMap` / `NuScenesMapExplorer` / `arcline_path_utils`
and on nuparquet's, the latter answering from the converted output alone (the map JSON deleted from its dataroot).

Run over every keyframe of the synthetic maps' scenes and a seeded set of poses per map (near the roads, off the map,
over empty ground, straddling its edges, at its corners). Geometry is compared exactly where it is copied, else to
1e-9 m (what shapely computes from the same coordinates in the same order is exact; the tolerance answers only a
rotation or intersection rounded differently); masks and integer arrays pixel for pixel; lists in the same order,
of the same types."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
import map_clients as mc  # noqa: E402
from geometry_same import assert_same  # noqa: E402

pytestmark = pytest.mark.devkit

GRID_POSES_PER_MAP = 14


@pytest.fixture(scope="module")
def poses(devkit, map_root, devkit_maps) -> list[dict]:
    """Every keyframe's poses, then GRID_POSES_PER_MAP seeded poses and the four corners of each map."""
    nusc = devkit.NuScenes("v1.0-synth", str(map_root), verbose=False)
    found = mc.keyframe_poses(nusc)
    for seed, (location, nusc_map) in enumerate(sorted(devkit_maps.items())):
        found += mc.grid_poses(nusc_map, location, found[0], GRID_POSES_PER_MAP, seed=seed)
    return found


@pytest.fixture(scope="module")
def theirs(devkit_maps):
    from nuscenes.map_expansion import arcline_path_utils, map_api

    return dict(map_api=map_api, arcline_path_utils=arcline_path_utils, maps=devkit_maps)


@pytest.fixture(scope="module")
def ours(map_root, map_out, devkit_maps, tmp_path_factory):
    """nuparquet's maps, over a copy of the dataroot without its map expansion JSON."""
    from nuparquet.devkit.map_expansion import arcline_path_utils, map_api

    dataroot = tmp_path_factory.mktemp("map-clients") / "data"
    shutil.copytree(map_root, dataroot, ignore=shutil.ignore_patterns("expansion"))
    assert not (dataroot / "maps" / "expansion").exists()
    maps = {location: map_api.NuScenesMap(str(dataroot), location, parquet=map_out) for location in devkit_maps}
    return dict(map_api=map_api, arcline_path_utils=arcline_path_utils, maps=maps)


def test_the_poses_reach_the_roads_the_crossings_and_beyond_the_maps(poses, theirs):
    """The inputs the clients are compared on: keyframes on the roads, grid poses with patches over ped crossings,
    and patches wholly off the map (an empty answer on both sides is part of the comparison)."""
    answers = mc.hdmapnet_samples(theirs["map_api"], theirs["maps"], poses)
    kinds = [{vector["type"] for vector in answer} for answer in answers]
    assert sum(1 for k in kinds if 1 in k) >= 3  # ped crossings in view
    assert sum(1 for k in kinds if not k) >= 5  # nothing in view
    assert sum(1 for k in kinds if {0, 2} <= k) >= 30  # dividers and road boundaries


def test_hdmapnet_vectorized_local_map(poses, theirs, ours):
    expected = mc.hdmapnet_samples(theirs["map_api"], theirs["maps"], poses)
    got = mc.hdmapnet_samples(ours["map_api"], ours["maps"], poses)
    assert sum(len(answer) for answer in expected) > 150
    assert_same(got, expected, "HDMapNet gen_vectorized_samples")


def test_maptr_v2_map_ground_truth_through_a_subclassed_explorer(poses, theirs, ours):
    expected = mc.maptr_infos(theirs["map_api"], theirs["maps"], poses)
    got = mc.maptr_infos(ours["map_api"], ours["maps"], poses)
    for vec_class in ("divider", "ped_crossing", "boundary", "centerline"):
        assert sum(len(answer[vec_class]) for answer in expected) > 3, vec_class
    assert_same(got, expected, "MapTR v2 obtain_vectormap")


def test_streammapnet_map_extractor(poses, theirs, ours):
    expected = mc.streammapnet_samples(theirs["map_api"], theirs["maps"], poses)
    got = mc.streammapnet_samples(ours["map_api"], ours["maps"], poses)
    for kind in ("divider", "ped_crossing", "boundary", "drivable_area"):
        assert sum(len(answer[kind]) for answer in expected) > 3, kind
    assert_same(got, expected, "StreamMapNet get_map_geom")


def test_bevfusion_bev_segmentation_masks_are_pixel_equal(poses, theirs, ours):
    expected = mc.bevfusion_samples(theirs["maps"], poses)
    got = mc.bevfusion_samples(ours["maps"], poses)
    stacked = np.stack(expected)
    assert stacked.dtype == np.int64 and stacked.shape[1:] == (6, 200, 200)
    assert all(stacked[:, k].any() for k in range(6))  # every class seen somewhere
    assert any(not mask.any() for mask in expected)  # and patches off the map
    assert_same(got, expected, "bevfusion LoadBEVSegmentation")


def test_trajdata_vector_maps(theirs, ours):
    expected = mc.trajdata_maps(theirs["arcline_path_utils"], theirs["maps"])
    got = mc.trajdata_maps(ours["arcline_path_utils"], ours["maps"])
    for vector_map in expected.values():
        lanes = vector_map["elements"]["ROAD_LANE"].values()
        assert sum(isinstance(lane.get("left_edge"), np.ndarray) for lane in lanes) > 20  # edges split
        assert sum(bool(lane["prev_lanes"]) for lane in lanes) > 20
        assert any(area["interior_holes"] for area in vector_map["elements"]["ROAD_AREA"].values())
    assert_same(got, expected, "trajdata populate_vector_map")


def test_pgp_lane_graphs(poses, theirs, ours):
    expected = mc.pgp_samples(theirs["maps"], poses)
    got = mc.pgp_samples(ours["maps"], poses)
    assert sum(len(answer["lane_ids"]) for answer in expected) > 500
    assert sum(sum(map(len, answer["e_prox"])) for answer in expected) > 500
    assert_same(got, expected, "PGP map_representation")


def test_bevfusion_where_a_divider_leaves_and_reenters_the_patch_the_devkit_raises_and_ours_draws_it(
        poses, theirs, ours, monkeypatch):
    """Under shapely 2 the devkit's `mask_for_lines` iterates a MultiLineString and raises, so bevfusion's loader
    fails on the devkit wherever a divider is cut in pieces by the patch; ours gives the mask the devkit drew under
    shapely 1 (its `mask_for_lines` with the parts iterated), pixel for pixel."""
    from nuscenes.map_expansion.map_api import NuScenesMapExplorer

    location = "boston-seaport"
    pose = mc.divider_cut_in_pieces(theirs["maps"][location], location, poses[0])
    assert pose is not None
    with pytest.raises(TypeError, match="not iterable"):
        mc.bevfusion_samples(theirs["maps"], [pose])
    got = mc.bevfusion_samples(ours["maps"], [pose])
    monkeypatch.setattr(NuScenesMapExplorer, "mask_for_lines", staticmethod(mc.mask_for_lines_as_in_shapely_1))
    expected = mc.bevfusion_samples(theirs["maps"], [pose])
    assert expected[0][5].any()  # the dividers drawn
    assert_same(got, expected, "bevfusion LoadBEVSegmentation, a divider in pieces")
