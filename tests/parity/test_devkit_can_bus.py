"""`nuparquet.devkit.can_bus.can_bus_api.NuScenesCanBus` against nuscenes-devkit's, on the real extract's CAN bus, the
generator's wild CAN bus files and an edge set made here (blacklisted, misaligned and scene-0419 names; key orders,
integers among floats, -0.0, NaN, nulls, objects, booleans and strings in messages; empty files; meta keys equal once
lower-cased; integer route points), with the JSON files removed after conversion: every `get_messages` answer (value,
types, key order, warnings, errors), the printers, the figures pixel for pixel, the misaligned routes, and three real
clients restated in `can_bus_clients.py` (BEVFormer, MapTR v2, the devkit's own tutorial)."""

from __future__ import annotations

import io
import json
import math
import pickle
import shutil
import sys
import warnings
from contextlib import redirect_stdout
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import polars as pl  # noqa: E402
import pytest  # noqa: E402
from PIL import Image  # noqa: E402

from can_bus_clients import bevformer_infos, can_bus_tutorial, maptr_infos  # noqa: E402
from conftest import SYNTH_VERSION, converted  # noqa: E402
from devkit_same import assert_same  # noqa: E402
from nuparquet.devkit.can_bus.can_bus_api import NuScenesCanBus  # noqa: E402
from nuparquet.errors import UsageError  # noqa: E402

RENAMED = {"scene-0001": "scene-0161", "scene-0002": "scene-0071", "scene-0003": "scene-0419"}
NOT_NAMES = ["scene-12", "scene-00001", "Scene-0004", "scene-004a"]


def _edit(path: Path, change) -> None:
    path.write_text(json.dumps(change(json.loads(path.read_text()))))


def _make_edge(root: Path) -> None:
    """Six scenes of the wild generator with the names and files the devkit treats apart (see the module docstring):
    scene-0161 (no CAN bus data for the devkit, files present), scene-0071 (misaligned route), scene-0419 (no
    vehicle_monitor messages), scene-0004 (every value shape), scene-0005 (empty ms_imu and zoesensors), scene-0006
    (a route, no other file)."""
    from nuparquet.synth import synthesize

    synthesize(root, scenes=6, samples_per_scene=6, seed=11, version=SYNTH_VERSION, wild_can_bus=True)
    scene_file = root / SYNTH_VERSION / "scene.json"
    scenes = json.loads(scene_file.read_text())
    for scene in scenes:
        scene["name"] = RENAMED.get(scene["name"], scene["name"])
    scene_file.write_text(json.dumps(scenes))
    for path in sorted((root / "can_bus").iterdir()):
        scene, rest = path.name.split("_", 1)
        path.rename(path.with_name(f"{RENAMED.get(scene, scene)}_{rest}"))
    can = root / "can_bus"

    def pose(messages):
        messages[3] = {k: messages[3][k] for k in reversed(list(messages[3]))}  # another key order
        messages[5]["vel"] = [0, 0.0, 0.0]  # an integer among floats, in a list
        messages[7]["accel"] = [-0.0, messages[7]["accel"][1], 9.81]
        return messages

    def steering(messages):
        messages[2]["value"] = 0  # an integer among floats
        messages[4]["value"] = float("nan")
        return messages

    def monitor(messages):  # fields every file of a message type has (the converter refuses a missing one)
        for i, m in enumerate(messages):
            m["mode"] = "auto" if i % 2 else "manual"
            m["flags"] = {"a": [1, 2.5], "b": None} if i % 3 else {}
            m["parked"] = i == 0
        return messages

    def meta(content):
        content["Pose"] = dict(content["POSE"], message_count=1)  # equal to POSE once lower-cased, as the devkit does
        return content

    _edit(can / "scene-0004_pose.json", pose)
    _edit(can / "scene-0004_steeranglefeedback.json", steering)
    for path in can.glob("*_vehicle_monitor.json"):
        _edit(path, monitor)
    _edit(can / "scene-0004_vehicle_monitor.json", lambda m: m[:1] + [dict(m[1], steering=None)] + m[2:])
    _edit(can / "scene-0004_meta.json", meta)
    _edit(can / "scene-0004_route.json", lambda r: [[int(x), y] for x, y in r[:3]] + r[3:])
    (can / "scene-0005_ms_imu.json").write_text("[]")
    (can / "scene-0005_zoesensors.json").write_text("[]")
    shutil.copy(can / "scene-0005_route.json", can / "scene-0006_route.json")  # a route without poses


@pytest.fixture(scope="module")
def edge(tmp_path_factory):
    """(the devkit's dataroot, ours, OUT): the CAN bus files are copied for the devkit, then deleted from the
    converted dataroot, so nothing of ours can read them."""
    root = tmp_path_factory.mktemp("can-edge") / "data"
    _make_edge(root)
    out = converted(tmp_path_factory, "can-edge-out", root, SYNTH_VERSION)
    devkit_root = tmp_path_factory.mktemp("can-edge-devkit")
    shutil.copytree(root / "can_bus", devkit_root / "can_bus")
    for path in (root / "can_bus").glob("*.json"):
        path.unlink()
    return devkit_root, root, out


@pytest.fixture(scope="module", params=["extract", "wild", "edge"])
def case(request):
    """(name, the devkit's NuScenesCanBus, ours, OUT, the devkit's dataroot)."""
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus as DevkitCanBus

    if request.param == "edge":
        devkit_root, root, out = request.getfixturevalue("edge")
    else:
        root = request.getfixturevalue("extract_root" if request.param == "extract" else "wild_can_root")
        out = request.getfixturevalue("extract_out" if request.param == "extract" else "wild_can_out")
        devkit_root = root
    return request.param, DevkitCanBus(dataroot=str(devkit_root)), NuScenesCanBus(parquet=out), out, devkit_root


# --- every answer is an outcome: a value or an error, with the warnings given on the way -------------------------

def _outcome(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            value, error = call(), None
        except Exception as exc:  # noqa: BLE001 - the devkit raises bare Exceptions: compared, not hidden
            value, error = None, exc
    return value, error, [(w.category, str(w.message)) for w in caught]


def _assert_same_outcome(ours, theirs, what):
    (value, error, warned), (expected, expected_error, expected_warned) = ours, theirs
    assert warned == expected_warned, what
    if expected_error is None:
        assert error is None, f"{what}: {error!r}"
        assert_same(value, expected, what)
        assert json.dumps(value) == json.dumps(expected), what  # -0.0, NaN, 0 vs 0.0, key order: JSON's spelling
        return
    assert type(error) is type(expected_error), f"{what}: {error!r} vs {expected_error!r}"
    if isinstance(expected_error, FileNotFoundError):  # ours says the file was not converted, beside its path
        assert (error.errno, Path(error.filename).name) == (expected_error.errno, Path(expected_error.filename).name)
    elif isinstance(expected_error, TypeError):  # Python's call errors name the function: the words after it
        assert str(error).split("() ", 1)[-1] == str(expected_error).split("() ", 1)[-1], what
    else:
        assert str(error) == str(expected_error), what


def _scenes(out: Path) -> list[str]:
    return pl.read_parquet(out / "tables" / "scene")["name"].to_list()


class _JsonOpens:
    """The files opened under a `can_bus/` folder inside `with` blocks of this object (an audit hook: the extract's
    JSON cannot be deleted, so opening it is what is checked)."""

    current: "_JsonOpens | None" = None
    installed = False

    def __init__(self):
        self.paths: list[str] = []
        if not _JsonOpens.installed:
            sys.addaudithook(_JsonOpens._seen)
            _JsonOpens.installed = True

    def __enter__(self):
        _JsonOpens.current = self

    def __exit__(self, *exc):
        _JsonOpens.current = None

    @staticmethod
    def _seen(event, args):
        watching = _JsonOpens.current
        if event == "open" and watching is not None and isinstance(args[0], (str, Path)) \
                and "can_bus" in Path(args[0]).parts and str(args[0]).endswith(".json"):
            watching.paths.append(str(args[0]))


def test_get_messages_is_the_devkits_for_every_scene_and_message(case):
    name, theirs, ours, out, _ = case
    counts = {"value": 0, "error": 0, "warning": 0}
    opened = _JsonOpens()
    for scene in _scenes(out) + NOT_NAMES:
        for message in theirs.all_messages + ["bogus", "MS_IMU"]:
            for print_warnings in (True, False):
                expected = _outcome(lambda: theirs.get_messages(scene, message, print_warnings))
                with opened:
                    got = _outcome(lambda: ours.get_messages(scene, message, print_warnings))
                _assert_same_outcome(got, expected, (scene, message, print_warnings))
                counts["value" if expected[1] is None else "error"] += 1
                counts["warning"] += len(expected[2])
    assert opened.paths == []
    assert counts["value"] >= 2 * 2 * 6 and counts["error"] > 0
    if name == "edge":  # the edge set reaches every branch: blacklist, misaligned route, scene-0419's warning
        assert counts["warning"] == 2  # scene-0071 route and scene-0419 vehicle_monitor, each with print_warnings
        errors = {type(_outcome(lambda: ours.get_messages(s, "pose"))[1]) for s in _scenes(out) + NOT_NAMES}
        assert errors == {type(None), Exception, FileNotFoundError, AssertionError}


def test_each_call_gives_new_objects_that_the_caller_may_change(case):
    """BEVFormer pops keys from the messages it is given, once per sample of the scene: the next call must give the
    file's messages again, as the devkit's fresh json.load does."""
    _, theirs, ours, out, _ = case
    scene = next(s for s in _scenes(out) if _outcome(lambda: theirs.get_messages(s, "pose"))[1] is None)
    first = ours.get_messages(scene, "pose")
    first[0].pop("utime")
    first[0]["pos"][0] = 1e9
    first.clear()
    assert_same(ours.get_messages(scene, "pose"), theirs.get_messages(scene, "pose"))
    meta = ours.get_messages(scene, "meta")
    meta.popitem()
    assert_same(ours.get_messages(scene, "meta"), theirs.get_messages(scene, "meta"))


def test_the_lists_and_names_are_the_devkits(case):
    _, theirs, ours, _, devkit_root = case
    for attribute in ("can_blacklist", "route_blacklist", "can_messages", "derived_messages", "all_messages"):
        assert_same(getattr(ours, attribute), getattr(theirs, attribute), attribute)
    assert NuScenesCanBus(dataroot=str(devkit_root), parquet=case[3]).can_dir == theirs.can_dir


def test_the_printers_print_what_the_devkits_print(case):
    _, theirs, ours, out, _ = case
    calls = [("print_all_message_stats", False), ("print_all_message_stats", True), ("print_message_stats", "pose"),
             ("print_message_stats", "zoesensors"), ("print_message_stats", "meta"), ("print_message_stats", "bogus")]
    printed = 0
    for scene in _scenes(out)[:4]:
        for method, argument in calls:
            outcomes = []
            for can in (theirs, ours):
                text = io.StringIO()
                with redirect_stdout(text):
                    outcome = _outcome(lambda: getattr(can, method)(scene, argument))
                outcomes.append((outcome, text.getvalue()))
            (got, got_text), (expected, expected_text) = outcomes[1], outcomes[0]
            _assert_same_outcome(got, expected, (scene, method, argument))
            assert got_text == expected_text, (scene, method, argument)
            printed += len(expected_text) > 0
    assert printed >= 3


def _picture(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGBA"))


PLOTS = [("plot_message_data", ("steeranglefeedback", "value")), ("plot_message_data", ("pose", "accel", 1)),
         ("plot_message_data", ("pose", "vel", -1)), ("plot_message_data", ("ms_imu", "q", 3, None, "r.")),
         ("plot_message_data", ("pose", "accel", 3)), ("plot_message_data", ("vehicle_monitor", "vehicle_speed", 1)),
         ("plot_message_data", ("vehicle_monitor", "no_such_key")), ("plot_baseline_route", ())]


def test_the_figures_are_the_devkits_pixel_for_pixel(case, tmp_path):
    _, theirs, ours, out, _ = case
    drawn = 0
    for scene in _scenes(out)[:5]:
        for k, (method, arguments) in enumerate(PLOTS):
            plt.close("all")
            results = []
            for who, can in (("devkit", theirs), ("ours", ours)):
                path = tmp_path / f"{scene}-{k}-{who}.png"
                extra = {"out_path": str(path)}
                results.append((_outcome(lambda: getattr(can, method)(scene, *arguments, **extra)), path,
                                len(plt.get_fignums())))
            (expected, expected_path, expected_open), (got, path, open_now) = results
            _assert_same_outcome(got, expected, (scene, method, arguments))
            assert open_now == 2 * expected_open  # the figure is left open for the caller, as the devkit leaves it
            if expected[1] is None:
                assert np.array_equal(_picture(path), _picture(expected_path)), (scene, method, arguments)
                drawn += 1
    plt.close("all")
    assert drawn >= 5


def _devkit_copy(root: Path, tmp_path: Path) -> Path:
    """The dataroot's CAN bus files without anything else (the devkit's list_misaligned_routes takes every file of the
    folder for a scene's: the extract's README.md fails its assertion)."""
    copy = tmp_path / "devkit-can"
    (copy / "can_bus").mkdir(parents=True)
    for path in (root / "can_bus").glob("scene-*_*.json"):
        shutil.copy(path, copy / "can_bus" / path.name)
    return copy


def test_misaligned_routes_and_the_computed_route_blacklist_are_the_devkits(case, tmp_path):
    """Thresholds between each pair of scene distances (so `>` against `>=` and a dropped scene show), and the
    route blacklist of another `max_misalignment`, which the devkit computes at 5 m whatever is asked (kept)."""
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus as DevkitCanBus

    from nuparquet.can_bus.routes import route_misalignment_m

    name, _, ours, out, devkit_root = case
    theirs = DevkitCanBus(dataroot=str(_devkit_copy(devkit_root, tmp_path)))
    if name == "edge":  # scene-0005's empty pose file stops both walks, scene-0161 the devkit's blacklist before it
        _assert_same_outcome(_outcome(ours.list_misaligned_routes), _outcome(theirs.list_misaligned_routes), name)
        _assert_same_outcome(_outcome(lambda: NuScenesCanBus(parquet=out, max_misalignment=3.0)),
                             _outcome(lambda: theirs.list_misaligned_routes(3.0)), name)
        assert isinstance(_outcome(ours.list_misaligned_routes)[1], FileNotFoundError)
        return
    distances = np.sort(route_misalignment_m(__import__("nuparquet").open(out))["misalignment_m"].to_numpy())
    low = float(distances[distances > 0][0]) / 2  # under every scene's distance but an exact 0
    thresholds = [0.0, 5.0, low, float(distances[-1]) * 2]
    thresholds += [float(a + b) / 2 for a, b in zip(distances, distances[1:])]
    answers = set()
    for threshold in thresholds:
        expected = theirs.list_misaligned_routes(threshold)
        assert_same(ours.list_misaligned_routes(threshold), expected, str(threshold))
        answers.add(tuple(expected))
    assert len(answers) == 1 + int((distances > 0).sum()) and () in answers  # each scene above 0 m adds one
    for max_misalignment in (low, 3.0):
        # the devkit's constructor fails here (AttributeError: it walks the routes before naming its messages);
        # ours is what it means, its own list_misaligned_routes at that distance
        with pytest.raises(AttributeError, match="all_messages"):
            DevkitCanBus(dataroot=str(theirs.can_dir)[:-len("/can_bus")], max_misalignment=max_misalignment)
        expected = [int(s[-4:]) for s in theirs.list_misaligned_routes(max_misalignment)]
        assert_same(NuScenesCanBus(parquet=out, max_misalignment=max_misalignment).route_blacklist, expected)
    assert NuScenesCanBus(parquet=out, max_misalignment=low).route_blacklist  # not the 5 m list
    if name == "extract":  # the devkit's own walk of the extract's folder, README.md and all, fails
        with pytest.raises(AssertionError):
            DevkitCanBus(dataroot=str(devkit_root)).list_misaligned_routes()


def test_a_pickled_copy_answers_the_same(case):
    _, theirs, ours, out, _ = case
    ours.route_blacklist = ours.route_blacklist + [4]  # a change the copy keeps, as a pickled devkit object does
    copy = pickle.loads(pickle.dumps(ours))
    assert copy.route_blacklist == ours.route_blacklist
    ours.route_blacklist = ours.route_blacklist[:-1]
    for scene in _scenes(out)[:3]:
        _assert_same_outcome(_outcome(lambda: copy.get_messages(scene, "pose", False)),
                             _outcome(lambda: theirs.get_messages(scene, "pose", False)), scene)


def test_the_output_is_found_as_the_devkit_nuscenes_finds_it(edge, tmp_path):
    devkit_root, root, out = edge
    assert NuScenesCanBus(dataroot=str(out)).can_dir == str(Path(root).resolve() / "can_bus")
    assert NuScenesCanBus(dataroot="/somewhere", parquet=out).can_dir == "/somewhere/can_bus"
    with pytest.raises(UsageError, match="is not a nuparquet output"):
        NuScenesCanBus(dataroot=str(devkit_root))
    with pytest.raises(UsageError, match="is not a nuparquet output"):
        NuScenesCanBus()  # the devkit's default /data/sets/nuscenes


def test_an_output_without_the_can_bus_is_refused_naming_why(tmp_path):
    from nuparquet.conversion import convert
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path / "data", scenes=1, samples_per_scene=2, seed=3, with_can_bus=False)
    convert(root, "v1.0-synth", tmp_path / "out")
    with pytest.raises(UsageError, match="holds no CAN bus datasets .*can_bus/ folder"):
        NuScenesCanBus(parquet=tmp_path / "out")


# --- real clients ---------------------------------------------------------------------------------------------------

def _nuscenes_pair(case):
    from nuscenes.nuscenes import NuScenes as DevkitNuScenes

    from nuparquet.devkit import NuScenes

    name, _, _, out, devkit_root = case
    version = json.loads((out / "manifest.json").read_text())["source"]["version"]
    dataroot = json.loads((out / "manifest.json").read_text())["source"]["dataroot"]
    return (DevkitNuScenes(version, dataroot=dataroot, verbose=False),
            NuScenes(version, dataroot=dataroot, parquet=out, verbose=False))


@pytest.mark.parametrize("client", [bevformer_infos, maptr_infos], ids=["bevformer", "maptr_v2"])
def test_bevformer_and_maptr_write_the_same_infos_on_both_and_nuparquet_computes_their_vector(case, client):
    """Both converters' info heads from the devkit's objects and from ours, every sample; their `can_bus` vector is
    also `sample_can_bus.can_bus` (nuparquet.can_bus.bevformer), bit for bit (values copied, no arithmetic)."""
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus as DevkitCanBus

    name, _, _, out, devkit_root = case
    devkit_nusc, our_nusc = _nuscenes_pair(case)
    expected = client(devkit_nusc, DevkitCanBus, str(devkit_root))
    opened = _JsonOpens()
    with opened:
        got = client(our_nusc, NuScenesCanBus, str(devkit_root), parquet=out)
    assert opened.paths == []
    assert_same(got, expected, client.__name__)
    native = dict(pl.read_parquet(out / "sample_can_bus").select("sample_token", "can_bus").iter_rows())
    for info in expected:
        assert np.array_equal(np.array(native[info["token"]]), info["can_bus"]), info["token"]
    zero = [not info["can_bus"].any() for info in expected]
    assert not all(zero)
    if name == "edge":  # scene-0161 (refused) and scene-0006 (no pose file): zeros
        by_scene = {devkit_nusc.get("scene", i["scene_token"])["name"]: z for i, z in zip(expected, zero)}
        assert by_scene == {"scene-0161": True, "scene-0071": False, "scene-0419": False, "scene-0004": False,
                            "scene-0005": False, "scene-0006": True}


def test_the_devkits_can_bus_tutorial_gives_the_same_on_both(wild_can_root, wild_can_out, tmp_path):
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus as DevkitCanBus

    for scene in ("scene-0001", "scene-0002"):
        results = {}
        for who, cls, options in (("devkit", DevkitCanBus, {}), ("ours", NuScenesCanBus, {"parquet": wild_can_out})):
            text = io.StringIO()
            with redirect_stdout(text):
                computed = can_bus_tutorial(cls, str(wild_can_root), scene,
                                            lambda n, w=who: str(tmp_path / f"{scene}-{n}-{w}.png"), **options)
            results[who] = computed, text.getvalue()
        assert_same(results["ours"][0], results["devkit"][0], scene)
        assert results["ours"][1] == results["devkit"][1] and '"zoe_veh_info": [' in results["devkit"][1]
        for figure in ("steeranglefeedback", "pose_accel", "speeds", "baseline_route"):
            assert np.array_equal(_picture(tmp_path / f"{scene}-{figure}-ours.png"),
                                  _picture(tmp_path / f"{scene}-{figure}-devkit.png")), (scene, figure)
        assert not math.isnan(results["ours"][0]["wheel_speed"][:, 1].sum())


def test_the_route_distances_are_cdists_and_refuse_what_cdist_refuses():
    """`list_misaligned_routes`' distances: scipy's `cdist(pose, route).min(axis=1)` (1e-12 m), and its errors for the
    arrays an empty or odd file gives (`np.asarray([])`, no route point, other widths), word for word."""
    import scipy.spatial.distance as scipy_dist

    from nuparquet.devkit.can_bus.can_bus_api import _nearest_distances

    rng = np.random.default_rng(5)
    pose, route = rng.normal(0, 300, (2500, 2)), rng.normal(0, 300, (700, 2))  # more poses than one block
    np.testing.assert_allclose(_nearest_distances(pose, route), scipy_dist.cdist(pose, route).min(axis=1),
                               rtol=1e-12, atol=1e-9)
    assert np.array_equal(_nearest_distances(np.asarray([[1, 2]]), np.asarray([[4, 6]])), [5.0])  # integers
    cases = [(np.asarray([]), route), (pose, np.asarray([])), (pose, np.zeros((0, 2))), (np.zeros((0, 2)), route),
             (pose, np.zeros((3, 3)))]
    for a, b in cases:
        expected = _outcome(lambda: np.max(scipy_dist.cdist(a, b).min(axis=1)))
        got = _outcome(lambda: np.max(_nearest_distances(a, b)))
        assert expected[1] is not None and type(got[1]) is type(expected[1]) and str(got[1]) == str(expected[1])


def test_the_misaligned_routes_walk_reads_what_get_pose_and_route_gives(case):
    """`list_misaligned_routes` reads x, y and pos as numbers (`_route_and_pose_xy`): the same arrays as the devkit's
    `get_pose_and_route`, and the same errors in the same order, for every scene."""
    _, theirs, ours, out, _ = case
    for scene in _scenes(out) + NOT_NAMES:
        expected = _outcome(lambda: theirs.get_pose_and_route(scene, print_warnings=False))
        got = _outcome(lambda: ours._route_and_pose_xy(scene))
        if expected[1] is None:
            assert got[1] is None, got[1]
            for mine, theirs_array in zip(got[0], expected[0]):
                assert mine.shape == theirs_array.shape and np.array_equal(mine, theirs_array.astype(np.float64))
        else:
            _assert_same_outcome(got, expected, scene)


def test_an_empty_pose_file_fails_the_walk_as_the_devkits(tmp_path):
    """An empty pose file: the devkit's `np.asarray([])` makes cdist refuse it; ours the same, word for word."""
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus as DevkitCanBus

    from nuparquet.conversion import convert
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path / "data", scenes=2, samples_per_scene=4, seed=2)
    (root / "can_bus" / "scene-0001_pose.json").write_text("[]")
    convert(root, "v1.0-synth", tmp_path / "out")
    theirs, ours = DevkitCanBus(dataroot=str(root)), NuScenesCanBus(parquet=tmp_path / "out")
    expected = _outcome(theirs.list_misaligned_routes)
    assert isinstance(expected[1], ValueError)
    _assert_same_outcome(_outcome(ours.list_misaligned_routes), expected, "walk")
    _assert_same_outcome(_outcome(lambda: ours.get_pose_and_route("scene-0001")[1].shape),
                         _outcome(lambda: theirs.get_pose_and_route("scene-0001")[1].shape), "shape")
