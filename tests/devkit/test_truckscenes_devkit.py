"""`nuparquet.devkit.truckscenes.TruckScenes` against truckscenes-devkit's `TruckScenes` (test-only) on generated
data: every table and its decorations, `get`/`getind`/`field2token`/`getclosest`, the boxes of `get_sample_data`
(a camera, a lidar and a radar channel, every visibility level, the flat frame), `get_boxes` of sweeps,
`boxes_to_sensor`, `box_velocity`, the printers and scene filters, and the clear refusals."""

from __future__ import annotations

import importlib
import json
import pickle
import shutil
import sys
import types
import warnings

import numpy as np
import pytest

from nuparquet.conversion import convert
from nuparquet.devkit import NotServed, NuScenes
from nuparquet.devkit.truckscenes import TruckScenes as Ours
from nuparquet.errors import InputError, UsageError
from nuparquet.synth import synthesize
from tests.conftest import converted, generated_root

truckscenes = pytest.importorskip("truckscenes")
from truckscenes import TruckScenes  # noqa: E402
from truckscenes.utils.geometry_utils import BoxVisibility  # noqa: E402

VERSION = "v1.2-mini"
LEVELS = (BoxVisibility.ALL, BoxVisibility.ANY, BoxVisibility.NONE)


def _devkit(root) -> TruckScenes:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its visualisation dependencies are not installed: no explorer
        return TruckScenes(VERSION, str(root), verbose=False)


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return generated_root(tmp_path_factory, "truckscenes-devkit", lambda path: synthesize(
        path, scenes=2, samples_per_scene=6, seed=3, family="truckscenes", version=VERSION))


@pytest.fixture(scope="module")
def out(root, tmp_path_factory):
    return converted(tmp_path_factory, "truckscenes-devkit-out", root, VERSION)  # the box calls read no points


@pytest.fixture(scope="module")
def ts(root):
    return _devkit(root)


@pytest.fixture(scope="module")
def ours(root, out):
    return Ours(VERSION, str(root), verbose=False, parquet=out)


def _same_boxes(theirs, mine, what):
    assert [b.token for b in mine] == [b.token for b in theirs], what  # the devkit's order, none more or fewer
    for a, b in zip(theirs, mine):
        np.testing.assert_array_equal(b.center, a.center, err_msg=str(what))  # the same arithmetic: exact
        np.testing.assert_array_equal(b.orientation.elements, a.orientation.elements, err_msg=str(what))
        np.testing.assert_array_equal(b.wlh, a.wlh, err_msg=str(what))
        assert b.name == a.name and np.isnan(b.velocity).all() == np.isnan(a.velocity).all(), what


def test_every_table_and_the_devkits_decorations_are_the_devkits(ts, ours):
    assert ours.table_names == ts.table_names
    for name in ts.table_names:
        theirs, mine = getattr(ts, name), getattr(ours, name)
        assert len(mine) == len(theirs) > 0, name
        assert mine == theirs, name  # records and the reverse-index fields, in file order
        assert [list(r) for r in mine] == [list(r) for r in theirs], name  # key order too
    assert not hasattr(ours, "log") and not hasattr(ours, "map")
    samples = list(ours.sample)
    assert all(len(s["data"]) == 16 for s in samples)  # every channel's keyframe, each under its own name
    assert [list(s["data"]) for s in samples] == [list(s["data"]) for s in ts.sample]  # in sample_data order
    assert sum(len(s["anns"]) for s in samples) == len(ts.sample_annotation)
    assert ours.colormap == ts.colormap and list(ours.colormap) == list(ts.colormap)


def test_get_getind_and_field2token_are_the_devkits(ts, ours):
    for i, record in enumerate(ts.sample):
        assert ours.get("sample", record["token"]) == record
        assert ours.get("sample", record["token"]) is ours.sample[i]  # one dict per record, as the devkit's list
        assert ours.getind("sample", record["token"]) == ts.getind("sample", record["token"]) == i
    for name in ("ego_motion_cabin", "ego_motion_chassis", "weather_annotation", "sample_data"):
        token = getattr(ts, name)[-1]["token"]
        assert ours.get(name, token) == ts.get(name, token) and ours.getind(name, token) == ts.getind(name, token)
    with pytest.raises(KeyError):
        ours.get("sample", "no such token")
    with pytest.raises(AssertionError, match="Table log not found"):
        ours.get("log", ts.scene[0]["log_token"])
    for table, field, query in [("sample_data", "channel", "RADAR_LEFT_SIDE"), ("sample_data", "is_key_frame", False),
                                ("sample", "scene_token", ts.scene[1]["token"]),
                                ("scene", "weather_annotation_token", ts.scene[1]["weather_annotation_token"]),
                                ("sample_annotation", "category_name", ts.sample_annotation[3]["category_name"])]:
        expected = ts.field2token(table, field, query)
        assert ours.field2token(table, field, query) == expected and expected, (table, field)


def test_getclosest_is_the_devkits_on_every_timed_table(ts, ours):
    for table in ("ego_pose", "ego_motion_cabin", "ego_motion_chassis", "sample", "sample_data"):
        stamps = sorted({r["timestamp"] for r in getattr(ts, table)})
        between = [(a + b) // 2 + d for a, b in zip(stamps, stamps[1:]) for d in (-1, 0, 1)]
        queries = [stamps[0] - 10**6, stamps[-1] + 10**6, *stamps[::5], *between[::4]]
        for t in queries:
            assert ours.getclosest(table, t) == ts.getclosest(table, t), (table, t)
    with pytest.raises(AssertionError, match="has no timestamp"):
        ours.getclosest("scene", 0)


@pytest.mark.parametrize("channel", ["CAMERA_RIGHT_BACK", "LIDAR_TOP_LEFT", "RADAR_LEFT_FRONT"])
def test_get_sample_data_is_the_devkits_for_a_camera_a_lidar_and_a_radar(ts, ours, channel):
    records = [r for r in ts.sample_data if r["channel"] == channel]
    kept = total = 0
    for record in records:
        for flat in (False, True):
            for level in LEVELS:
                path, boxes, intrinsic = ts.get_sample_data(record["token"], box_vis_level=level,
                                                            use_flat_vehicle_coordinates=flat)
                my_path, mine, my_intrinsic = ours.get_sample_data(record["token"], box_vis_level=level,
                                                                   use_flat_vehicle_coordinates=flat)
                assert my_path == path == ours.get_sample_data_path(record["token"])
                assert path.endswith(record["filename"]) and f"/{channel}/" in path
                _same_boxes(boxes, mine, (record["token"], flat, level))
                if intrinsic is None:
                    assert my_intrinsic is None
                else:
                    np.testing.assert_array_equal(my_intrinsic, intrinsic)
                kept += len(boxes) if level == BoxVisibility.ANY else 0
                total += len(boxes) if level == BoxVisibility.NONE else 0
        selected = ts.sample_annotation[::7]
        tokens = [a["token"] for a in selected]
        _same_boxes(ts.get_sample_data(record["token"], selected_anntokens=tokens)[1],
                    ours.get_sample_data(record["token"], selected_anntokens=tokens)[1], record["token"])
    assert kept > 0 and not all(r["is_key_frame"] for r in records)  # sweeps too
    if channel.startswith("CAMERA"):
        assert kept < total  # some boxes are out of the image
    else:
        assert kept == total


def test_boxes_of_sweeps_are_the_devkits_get_boxes(ts, ours):
    sweeps = [r for r in ts.sample_data if not r["is_key_frame"]]
    moved = 0
    for record in sweeps:
        theirs = ts.get_boxes(record["token"])
        _same_boxes(theirs, ours.get_boxes(record["token"]), record["token"])
        moved += sum(not np.array_equal(b.center, ts.get("sample_annotation", b.token)["translation"])
                     for b in theirs)
    assert len(sweeps) > 100 and moved > 100  # interpolated between the samples, not the annotations' own


def test_boxes_to_sensor_is_the_devkits(ts, ours):
    record = next(r for r in ts.sample_data if r["channel"] == "LIDAR_REAR" and not r["is_key_frame"])
    pose = ts.get("ego_pose", record["ego_pose_token"])
    calibration = ts.get("calibrated_sensor", record["calibrated_sensor_token"])
    for flat in (False, True):
        theirs = ts.get_boxes(record["token"])
        for box in theirs:
            box.velocity = np.array([1.0, -2.0, 0.5])
        mine = ours.get_boxes(record["token"])
        for box in mine:
            box.velocity = np.array([1.0, -2.0, 0.5])
        theirs = ts.boxes_to_sensor(theirs, pose, calibration, use_flat_vehicle_coordinates=flat)
        mine = ours.boxes_to_sensor(mine, pose, calibration, use_flat_vehicle_coordinates=flat)
        _same_boxes(theirs, mine, flat)
        np.testing.assert_array_equal([b.velocity for b in mine], [b.velocity for b in theirs])


def test_box_velocity_is_the_devkits_nan_where_theirs_is(ts, ours):
    expected = np.array([ts.box_velocity(a["token"]) for a in ts.sample_annotation])
    got = np.array([ours.box_velocity(a["token"]) for a in ts.sample_annotation])
    np.testing.assert_array_equal(got, expected)
    assert 0 < np.isnan(expected[:, 0]).sum() < len(expected)
    short = np.array([ours.box_velocity(a["token"], max_time_diff=0.3) for a in ts.sample_annotation])
    np.testing.assert_array_equal(short, [ts.box_velocity(a["token"], max_time_diff=0.3)
                                          for a in ts.sample_annotation])
    assert np.isnan(short[:, 0]).sum() > np.isnan(expected[:, 0]).sum()


@pytest.fixture
def their_explorer(ts):
    """The devkit's own explorer over its object: open3d (for its renderers only) is not installed, so a stand-in
    module takes its place while it is imported."""
    name = "truckscenes.utils.visualization_utils"
    saved = {key: sys.modules.get(key) for key in ("open3d", name)}
    sys.modules["open3d"] = types.ModuleType("open3d")
    try:
        yield importlib.import_module(name).TruckScenesExplorer(ts)
    finally:
        for key, module in saved.items():
            if module is None:
                sys.modules.pop(key, None)
            else:
                sys.modules[key] = module


def test_the_printers_and_scene_filters_are_the_devkits_explorer(ts, ours, their_explorer, capsys):
    for call, args in [("list_categories", ()), ("list_attributes", ()), ("list_scenes", ()),
                       ("list_sample", (ts.sample[7]["token"],))]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # utcfromtimestamp
            getattr(their_explorer, call)(*args)
        expected = capsys.readouterr().out
        getattr(ours, call)(*args)
        assert capsys.readouterr().out == expected and expected.count("\n") >= 2, call
    weather = ts.weather_annotation
    split = (weather[0]["temperature"] + weather[1]["temperature"]) / 2
    for conditions in ([("temperature", ">", split)], [("temperature", "<=", split), ("wind", ">=", 0.0)],
                       [("precipitation", "==", weather[1]["precipitation"])], [("visibility", "!=", 0.0)]):
        expected = their_explorer.get_scenes_weather_annotations_filtered(conditions)
        assert ours.get_scenes_weather_annotations_filtered(conditions) == expected, conditions
    assert len(ours.get_scenes_weather_annotations_filtered([("temperature", ">", split)])) == 1
    word = ts.scene[0]["description"].split(";")[0]
    for conditions in ([(word, "==")], [(word, "!=")], [("area.", "=="), ("nowhere", "!=")]):
        expected = their_explorer.get_scenes_description_filtered(conditions)
        assert ours.get_scenes_description_filtered(conditions) == expected, conditions
    with pytest.raises(AssertionError, match="Invalid field"):
        ours.get_scenes_weather_annotations_filtered([("token", "==", 1.0)])


def test_what_is_not_served_says_what_to_use_and_nuscenes_only_calls_are_absent(ts, ours):
    token = ts.sample[0]["token"]
    for call in ("render_sample", "render_scene", "render_pointcloud", "render_calibrated_sensor"):
        with pytest.raises(NotServed, match=f"{call} is not served.*nuparquet render"):
            getattr(ours, call)(token)
    from nuparquet.devkit.utils.data_classes import LidarPointCloud

    with pytest.raises(NotServed, match="multisweep"):
        LidarPointCloud.from_file_multisweep(ours, ts.sample[3], "LIDAR_LEFT", "LIDAR_LEFT", nsweeps=2)
    for name in ("list_lidarseg_categories", "get_sample_lidarseg_stats", "render_egoposes_on_map", "map"):
        assert hasattr(ours, name) is hasattr(ts, name) is False, name
    copy = pickle.loads(pickle.dumps(ours))
    assert copy.sample == ts.sample and copy.dataroot == ours.dataroot


def test_outputs_of_another_family_are_refused_naming_the_format(root, out, tmp_path):
    with pytest.raises(InputError, match=r"MAN TruckScenes \(source format 'truckscenes'\).*"
                                         r"nuparquet\.devkit\.truckscenes\.TruckScenes"):
        NuScenes(VERSION, str(root), parquet=out, verbose=False)
    nuscenes_root = synthesize(tmp_path / "nusc", scenes=1, samples_per_scene=2, seed=5, version="v1.0-mini",
                               with_can_bus=False)
    convert(nuscenes_root, "v1.0-mini", tmp_path / "nusc-out")
    with pytest.raises(InputError, match=r"nuScenes \(source format 'nuscenes'\).*nuparquet\.devkit\.NuScenes"):
        Ours("v1.0-mini", parquet=tmp_path / "nusc-out", verbose=False)
    with pytest.raises(UsageError, match="pass version='v1.2-mini'"):
        Ours("v1.1-mini", parquet=out, verbose=False)
    assert Ours(parquet=out, verbose=False).version == VERSION  # None: the converted one


def test_without_weather_annotation_the_table_is_empty_as_the_devkit_loads_it(root, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(root / VERSION, copy / VERSION)
    (copy / VERSION / "weather_annotation.json").unlink()
    scenes = json.loads((copy / VERSION / "scene.json").read_text())
    for scene in scenes:
        scene.pop("weather_annotation_token")
    (copy / VERSION / "scene.json").write_text(json.dumps(scenes, indent=2))
    convert(copy, VERSION, tmp_path / "out")
    ts = _devkit(copy)
    with pytest.warns(UserWarning, match="weather_annotations.json was not found"):
        ours = Ours(VERSION, str(copy), parquet=tmp_path / "out", verbose=False)
    assert ours.weather_annotation == ts.weather_annotation == [] and ours.scene == ts.scene
    assert ours.field2token("weather_annotation", "wind", 1.0) == []
    assert ours.get_scenes_weather_annotations_filtered([("wind", ">", 0.0)]) == []
    with pytest.raises(KeyError):
        ours.get("weather_annotation", "anything")
