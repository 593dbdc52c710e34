"""Shared fixtures: the real nuScenes extract (skipped cleanly when ../shared is absent), small synthetic
datasets, and their conversions. Conversions are session-scoped: every test reads them, none writes them."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
EXTRACT_ROOT = REPO.parent / "shared" / "data" / "nuscenes-extract"
EXTRACT_VERSION = "v1.0-mini-extract"
SYNTH_VERSION = "v1.0-synth"
# The sensor channels of nuScenes (and of the generator's default rig).
NUSCENES_CHANNELS = {"CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_BACK_RIGHT", "CAM_BACK", "CAM_BACK_LEFT", "CAM_FRONT_LEFT",
                     "LIDAR_TOP", "RADAR_FRONT", "RADAR_FRONT_LEFT", "RADAR_FRONT_RIGHT", "RADAR_BACK_LEFT",
                     "RADAR_BACK_RIGHT"}


# --- no skipped parity tests where they can run ---------------------------------------------------------------
# Parity tests (tests/parity/, anything using the devkit, anything marked devkit or real) may skip only where
# ../shared is absent (a user's fresh clone). Where it is present (CI, the developers' machines) a skip of one
# of them fails the run: the controller sees every report, with or without pytest-xdist.

PARITY_DIR = REPO / "tests" / "parity"
_parity_skips: list[str] = []

# Browser tests (marked browser) drive Debian's Chromium; they may skip only where it is not installed (or, for those
# of the real extract, where ../shared is absent). Where it is (CI installs it in .ci/run), a skipped browser test
# fails the run like a skipped parity test.
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_INSTALL = "apt-get update && apt-get install -y --no-install-recommends chromium"
_browser_skips: list[str] = []


def _shared_present() -> bool:
    return (EXTRACT_ROOT / EXTRACT_VERSION).is_dir()


def pytest_collection_modifyitems(config, items):
    for item in items:
        names = getattr(item, "fixturenames", ())
        if "devkit" in names or Path(str(item.path)).is_relative_to(PARITY_DIR):
            item.add_marker(pytest.mark.devkit)
        if "extract_root" in names:
            item.add_marker(pytest.mark.real)
        if "chromium" in names:
            item.add_marker(pytest.mark.browser)


def pytest_runtest_logreport(report):
    if not report.skipped or hasattr(report, "wasxfail"):
        return
    reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
    if "devkit" in report.keywords or "real" in report.keywords:
        _parity_skips.append(f"{report.nodeid}: {reason}")
    # a browser test of the real extract may skip where ../shared is absent (a user's clone), Chromium or not
    if "browser" in report.keywords and not ("real" in report.keywords and not _shared_present()):
        _browser_skips.append(f"{report.nodeid}: {reason}")


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session, exitstatus):
    if hasattr(session.config, "workerinput"):  # an xdist worker: its reports reach the controller
        return
    if _parity_skips and _shared_present() and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
    if _browser_skips and CHROMIUM.exists() and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if _parity_skips and _shared_present():
        terminalreporter.section("parity tests skipped although ../shared is present", red=True)
        for line in _parity_skips:
            terminalreporter.write_line(line, red=True)
        terminalreporter.write_line(f"error: {len(_parity_skips)} parity/devkit test(s) skipped: the run fails "
                                    "(they may skip only where ../shared is absent)", red=True)
    if _browser_skips and CHROMIUM.exists():
        terminalreporter.section(f"browser tests skipped although {CHROMIUM} is installed", red=True)
        for line in _browser_skips:
            terminalreporter.write_line(line, red=True)


@pytest.fixture(scope="session", autouse=True)
def _serial_engine_for_mutation_runs():
    """NUPARQUET_TEST_SERIAL_ENGINE (set by mutation/run.py for every group but the engine's own): the process-pool
    engine runs its units in this process. mutmut maps a function to the tests during which it ran in the test's
    own process, and it runs a mutant against those tests only: code a worker process ran (a conversion's scene
    points) would have no test and its mutants none either."""
    if os.environ.get("NUPARQUET_TEST_SERIAL_ENGINE"):
        from nuparquet.engine import backends

        backends.BACKENDS["process"] = backends.serial
    yield


@pytest.fixture(scope="session")
def chromium() -> Path:
    """Debian's Chromium for the browser tests (Playwright drives it; no browser is ever downloaded). Absent: the
    test skips, saying how to install it."""
    if not CHROMIUM.exists():
        pytest.skip(f"headless Chromium not found at {CHROMIUM}: install Debian's chromium ({CHROMIUM_INSTALL}) to "
                    "run the browser tests")
    return CHROMIUM


@pytest.fixture(scope="session")
def extract_root() -> Path:
    if not (EXTRACT_ROOT / EXTRACT_VERSION).is_dir():
        pytest.skip("real nuScenes extract not present (../shared/data/nuscenes-extract)")
    return EXTRACT_ROOT


@pytest.fixture(scope="session")
def extract_out(extract_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "extract", extract_root, EXTRACT_VERSION)


def generated_root(tmp_path_factory, name: str, make, cache: str | None = None) -> Path:
    """A dataroot written by `make(root)` (the generator): in a fresh temporary directory, or, when
    NUPARQUET_TEST_CACHE (or `cache`) names a directory (the mutation runs, which start pytest once per mutant),
    made once there and reused. The generator is deterministic, and the mutation group that mutates it runs
    without the cache, so the cache cannot go stale within a run.

    Several pytest-xdist workers may ask for the same cached dataset at once: the first takes an exclusive lock on
    `<cache>/<name>.lock` and builds; the others wait on the lock, then find it complete. The build writes into a
    private folder renamed into place, so a reader never sees half a dataset (and a killed build leaves none)."""
    cache = cache or os.environ.get("NUPARQUET_TEST_CACHE")
    if not cache:
        root = tmp_path_factory.mktemp(name) / "data"
        make(root)
        return root
    import fcntl
    import shutil

    home = Path(cache) / name
    root, complete = home / "data", home / ".complete"
    home.parent.mkdir(parents=True, exist_ok=True)
    with open(Path(cache) / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, or when the process dies
        if not complete.exists():
            building = Path(cache) / f".{name}.building-{os.getpid()}"
            shutil.rmtree(building, ignore_errors=True)
            shutil.rmtree(home, ignore_errors=True)  # an earlier, killed build
            make(building / "data")
            (building / ".complete").touch()
            os.replace(building, home)
    return root


def converted(tmp_path_factory, name: str, root: Path, version: str, **options) -> Path:
    """`nuparquet convert` of `root`/`version` into a fresh temporary OUT (the session's converted fixtures).

    When NUPARQUET_TEST_CACHE_CONVERSIONS names a directory (a mutation group none of whose modules a conversion
    runs: mutation/run.py), a conversion of a dataroot that outlives the session (a cached generated one, the real
    extract) is made once there, by the group's first, unmutated test run, and reused by every mutant's;
    `generated_root`'s lock makes it safe under concurrency."""
    from nuparquet.conversion import convert

    cache = os.environ.get("NUPARQUET_TEST_CACHE_CONVERSIONS")
    # a root made in this session's temporary folder is made afresh (at another path) by every run: not cached
    if cache and not Path(root).resolve().is_relative_to(tmp_path_factory.getbasetemp().resolve()):
        import hashlib
        import json

        key = hashlib.sha256(json.dumps([str(root), version, options], sort_keys=True, default=str).encode())
        made = generated_root(tmp_path_factory, f"{name}-{key.hexdigest()[:12]}",
                              lambda out: convert(root, version, out, **options), cache=cache)
        return made
    out = tmp_path_factory.mktemp(name) / "out"
    convert(root, version, out, **options)
    return out


@pytest.fixture(scope="session")
def extract_points_out(extract_root, tmp_path_factory) -> Path:
    """The real extract converted with its sensor points (lidar_points/, radar_points/), one process."""
    return converted(tmp_path_factory, "extract-points", extract_root, EXTRACT_VERSION, sensors=("lidar", "radar"),
                     workers=1)


@pytest.fixture(scope="session")
def labelled_root(tmp_path_factory) -> Path:
    """2 scenes x 3 samples with lidar/radar keyframes and sweeps and lidarseg/panoptic labels, no CAN bus."""
    from nuparquet.synth import synthesize

    return generated_root(tmp_path_factory, "labelled", lambda root: synthesize(
        root, scenes=2, samples_per_scene=3, with_lidar=True, seed=11, version=SYNTH_VERSION, with_can_bus=False))


@pytest.fixture(scope="session")
def lidarseg_root(tmp_path_factory) -> Path:
    """3 scenes x 4 samples with images, lidar files and lidarseg labels: scene-0001/0002 are in the devkit's
    trainval train list, scene-0003 in val (the training-index tests need both splits)."""
    from nuparquet.synth import synthesize

    return generated_root(tmp_path_factory, "lidarseg", lambda root: synthesize(
        root, scenes=3, samples_per_scene=4, with_images=True, with_lidar=True, seed=13, version=SYNTH_VERSION,
        with_can_bus=False))


@pytest.fixture(scope="session")
def lidarseg_out(lidarseg_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "lidarseg-out", lidarseg_root, SYNTH_VERSION)


@pytest.fixture(scope="session")
def synth_root(tmp_path_factory) -> Path:
    """A small synthetic dataset with images and lidar: 2 scenes x 6 samples."""
    from nuparquet.synth import synthesize

    return generated_root(tmp_path_factory, "synth", lambda root: synthesize(
        root, scenes=2, samples_per_scene=6, with_images=True, with_lidar=True, seed=7, version=SYNTH_VERSION))


@pytest.fixture(scope="session")
def synth_out(synth_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "synth-out", synth_root, SYNTH_VERSION)


@pytest.fixture(scope="session")
def synth_points_out(synth_root, tmp_path_factory) -> Path:
    """`synth_root` converted with every lidar and radar point, sweeps included (lidar_points/, radar_points/)."""
    return converted(tmp_path_factory, "synth-points-out", synth_root, SYNTH_VERSION, sensors=("lidar", "radar"),
                     sweeps=True, workers=1)


@pytest.fixture(scope="session")
def synth_report(synth_points_out, tmp_path_factory):
    """`nuparquet report` of every scene of `synth_points_out` (videos and keyframe renderings, one process), and
    its progress events."""
    from nuparquet.engine import EngineOptions
    from nuparquet.site import ReportOptions, build_report

    out = tmp_path_factory.mktemp("report") / "report"
    events = []
    result = build_report(synth_points_out, None, out, engine=EngineOptions(engine="serial"),
                          on_progress=events.append)
    return result, events


@pytest.fixture(scope="session")
def real_report(extract_out, tmp_path_factory):
    """`nuparquet report` of the real extract's two scenes (keyframe images only: the sweeps are absent)."""
    from nuparquet.engine import EngineOptions
    from nuparquet.site import ReportOptions, build_report

    out = tmp_path_factory.mktemp("report-real") / "report"
    return build_report(extract_out, None, out, ReportOptions(video_scale=0.2, stills=2),
                        engine=EngineOptions(engine="serial"))


@pytest.fixture(scope="session")
def six_scene_report(map_out, tmp_path_factory):
    """`nuparquet report --no-videos` of the 6-scene synthetic dataset (tables only): a scene table to sort."""
    from nuparquet.engine import EngineOptions
    from nuparquet.site import ReportOptions, build_report

    out = tmp_path_factory.mktemp("report-six") / "report"
    return build_report(map_out, None, out, ReportOptions(videos=False), engine=EngineOptions(engine="serial"))


@pytest.fixture(scope="session")
def devkit():
    """The nuscenes-devkit module (test-only reference implementation). Not installed is a failure, never a
    skip: `make test` installs it, and a parity test that silently stops running hides regressions."""
    import nuscenes.nuscenes

    return nuscenes.nuscenes


@pytest.fixture(scope="session")
def wild_can_root(tmp_path_factory) -> Path:
    """3 scenes x 8 samples, tables only, with the CAN bus files of scenes 1 and 2 in the shapes real ones take
    (`synth.can_bus`, wild): every stream starting after the second keyframe, a zoesensors stream, a pose gap of
    exactly 1 s and a steeranglefeedback gap of 1 s + 1 us, a vehicle_monitor message missing, mixed-case meta keys,
    var_stats objects (VEHICLE_MONITOR's in scene-0001 only)."""
    from nuparquet.synth import synthesize

    return generated_root(tmp_path_factory, "wild-can", lambda root: synthesize(
        root, scenes=3, samples_per_scene=8, seed=4, version=SYNTH_VERSION, wild_can_bus=True))


@pytest.fixture(scope="session")
def wild_can_out(wild_can_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "wild-can-out", wild_can_root, SYNTH_VERSION)


LYFT_RIG_VERSION = "v1.0-lyft-rig"


@pytest.fixture(scope="session")
def lyft_rig_root(tmp_path_factory) -> Path:
    """A synthetic dataset with a Lyft Level 5-like sensor set: seven cameras (CAM_FRONT_ZOOMED among them;
    1224x1024 images, the zoomed one 2048x864), three lidars (LIDAR_TOP, LIDAR_FRONT_LEFT, LIDAR_FRONT_RIGHT),
    no radar. One scene x 4 samples, with images and lidar files."""
    from nuparquet.synth import synthesize

    return generated_root(tmp_path_factory, "lyft-rig", lambda root: synthesize(
        root, scenes=1, samples_per_scene=4, with_images=True, with_lidar=True, seed=11, version=LYFT_RIG_VERSION,
        rig="lyft"))


@pytest.fixture(scope="session")
def lyft_rig_out(lyft_rig_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "lyft-rig-out", lyft_rig_root, LYFT_RIG_VERSION)


@pytest.fixture(scope="session")
def tiny_map_root(tmp_path_factory) -> Path:
    """One scene, two samples, one map: the input the bad-map tests damage, each in its own copy (`small_map_root`;
    a conversion takes a fraction of a second)."""
    from nuparquet.synth import synthesize

    return synthesize(tmp_path_factory.mktemp("tiny-map") / "data", scenes=1, samples_per_scene=2, seed=9,
                      version=SYNTH_VERSION, with_can_bus=False)


@pytest.fixture
def small_map_root(tiny_map_root, tmp_path) -> Path:
    """A fresh copy of `tiny_map_root` for a test to damage."""
    copy = tmp_path / "data"
    shutil.copytree(tiny_map_root, copy)
    return copy


def first_map(root: Path) -> Path:
    """The first map expansion file of a dataroot."""
    return sorted((root / "maps" / "expansion").glob("*.json"))[0]


@pytest.fixture(scope="session")
def map_root(tmp_path_factory) -> Path:
    """6 scenes x 4 samples, tables only: four locations, two of them with two roads."""
    from nuparquet.synth import synthesize

    return generated_root(tmp_path_factory, "map-synth", lambda root: synthesize(
        root, scenes=6, samples_per_scene=4, seed=5, version=SYNTH_VERSION, with_can_bus=False))


@pytest.fixture(scope="session")
def map_out(map_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "map-out", map_root, SYNTH_VERSION)


@pytest.fixture(scope="session")
def devkit_maps(map_root) -> dict:
    """{location: NuScenesMap} for every synthetic map (the reference)."""
    from nuscenes.map_expansion.map_api import NuScenesMap

    return {p.stem: NuScenesMap(str(map_root), p.stem) for p in sorted((map_root / "maps" / "expansion").glob("*.json"))}


IRREGULAR_VERSION = "v1.0-irregular"
IRREGULAR_EMPTY_VERSION = IRREGULAR_VERSION + "-test"  # same tables, empty annotation tables


@pytest.fixture(scope="session")
def irregular_root(tmp_path_factory) -> Path:
    """The generator's irregular profile (`synth.irregular`): 2 scenes x 9 samples with images and lidar, tracks
    with 1-3 s gaps, hills, boxes 0.05-1.5 m in front of CAM_FRONT, clock ties, a late first CAM_FRONT frame,
    and IRREGULAR_EMPTY_VERSION beside IRREGULAR_VERSION."""
    from nuparquet.synth import synthesize

    return generated_root(tmp_path_factory, "irregular", lambda root: synthesize(
        root, scenes=2, samples_per_scene=9, with_images=True, with_lidar=True, seed=5, version=IRREGULAR_VERSION,
        profile="irregular"))


@pytest.fixture(scope="session")
def irregular_out(irregular_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "irregular-out", irregular_root, IRREGULAR_VERSION)


@pytest.fixture(scope="session")
def irregular_empty_out(irregular_root, tmp_path_factory) -> Path:
    """The conversion of the version folder whose sample_annotation and instance tables are empty."""
    return converted(tmp_path_factory, "irregular-empty-out", irregular_root, IRREGULAR_EMPTY_VERSION)


# --- detection evaluation (tests/evaluation/) ----------------------------------------------------------------------
# A synthetic dataroot named v1.0-trainval, so the devkit evaluates its scenes that are in the real val list
# (scene-0003, scene-0012, scene-0013), edited for the hard cases (tests/evaluation/eval_edits.py), converted once;
# the devkit's NuScenes over it; and submissions made from it (tests/evaluation/eval_submissions.py).

EVAL_VERSION = "v1.0-trainval"


def _evaluation_helpers() -> None:
    """tests/evaluation/ on sys.path: its helper modules (eval_edits, eval_submissions) are imported by name."""
    import sys

    folder = str(REPO / "tests" / "evaluation")
    if folder not in sys.path:
        sys.path.insert(0, folder)


@pytest.fixture(scope="session")
def eval_data(tmp_path_factory) -> tuple[Path, dict]:
    from nuparquet.synth import synthesize

    _evaluation_helpers()
    from eval_edits import edit_dataset

    root = synthesize(tmp_path_factory.mktemp("eval-synth") / "data", scenes=13, samples_per_scene=6, seed=3,
                      version=EVAL_VERSION, with_can_bus=False)
    return root, edit_dataset(root, EVAL_VERSION)


@pytest.fixture(scope="session")
def eval_root(eval_data) -> Path:
    return eval_data[0]


@pytest.fixture(scope="session")
def eval_edits(eval_data) -> dict:
    """What `eval_edits.edit_dataset` placed where (tokens), for the tests' preconditions."""
    return eval_data[1]


@pytest.fixture(scope="session")
def eval_out(eval_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "eval-out", eval_root, EVAL_VERSION)


@pytest.fixture(scope="session")
def eval_nusc(devkit, eval_root):
    return devkit.NuScenes(EVAL_VERSION, str(eval_root), verbose=False)


@pytest.fixture(scope="session")
def submissions(eval_nusc, eval_edits, tmp_path_factory) -> dict[str, Path]:
    """name -> results.json: perfect, noisy (two seeds), edges."""
    _evaluation_helpers()
    import eval_submissions as make

    folder = tmp_path_factory.mktemp("eval-submissions")
    files = {"perfect": make.write(folder / "perfect.json", make.perfect(eval_nusc)),
             "noisy": make.write(folder / "noisy.json", make.noisy(eval_nusc, seed=1)),
             "noisy2": make.write(folder / "noisy2.json", make.noisy(eval_nusc, seed=2))}
    files["edges"] = make.write(folder / "edges.json", make.edge_cases(eval_nusc, eval_edits)[0])
    return files


@pytest.fixture(scope="session")
def edge_placement(eval_nusc, eval_edits) -> dict:
    """What the edge-case submission placed where."""
    _evaluation_helpers()
    import eval_submissions as make

    return make.edge_cases(eval_nusc, eval_edits)[1]


# --- nuparquet.devkit: the devkit's NuScenes served from the Parquet (tests/parity/test_devkit_*.py) ---------------

@pytest.fixture(scope="session")
def labelled_out(labelled_root, tmp_path_factory) -> Path:
    """The labelled set converted with its lidar and radar keyframe points and its lidarseg/panoptic tables."""
    return converted(tmp_path_factory, "labelled-out", labelled_root, SYNTH_VERSION, sensors=("lidar", "radar"), workers=1)


@pytest.fixture(scope="session")
def layouts_root(tmp_path_factory) -> Path:
    """A small dataroot (tables and maps) whose JSON is as irregular as derived datasets': Lyft's absent or NaN
    width/height, other key orders, integers in float lists and one written as a float, an extra field holding an
    object, empty visibility tokens, a log with a map_token of its own, and an image_annotations table."""
    import json
    import math

    from nuparquet.synth import synthesize

    root = synthesize(tmp_path_factory.mktemp("layouts") / "data", scenes=2, samples_per_scene=4, seed=3,
                      version=SYNTH_VERSION, with_can_bus=False)
    folder = root / SYNTH_VERSION

    def edit(table, change):
        records = json.loads((folder / f"{table}.json").read_text())
        change(records)
        (folder / f"{table}.json").write_text(json.dumps(records))  # NaN as the literal NaN, as Lyft writes it

    sensors = {s["token"]: s["modality"] for s in json.loads((folder / "sensor.json").read_text())}
    modality = {c["token"]: sensors[c["sensor_token"]] for c in json.loads((folder / "calibrated_sensor.json").read_text())}

    def sample_data(records):
        for r in records:
            if modality[r["calibrated_sensor_token"]] == "radar":
                del r["width"], r["height"]
            elif modality[r["calibrated_sensor_token"]] == "lidar":
                r["width"], r["height"] = math.nan, math.nan
        records[5]["timestamp"] = float(records[5]["timestamp"])
        records[7]["extra"] = {"a": [1, 2.5, None], "b": "x"}

    def annotations(records):
        for r in records[::3]:
            r["visibility_token"] = ""
        records[2] = dict(reversed(list(records[2].items())))
        records[4]["rotation"] = [1, 0, 0, 0]

    def calibrations(records):
        next(c for c in records if modality[c["token"]] == "lidar")["rotation"] = [1, 0, 0, 0]
        next(c for c in records if modality[c["token"]] == "camera")["camera_intrinsic"] = [
            [1266, 0.0, 816.5], [0, 1266.4, 491], [0, 0, 1]]

    edit("sample_data", sample_data)
    edit("sample_annotation", annotations)
    edit("sample", lambda records: records.__setitem__(slice(0, 3), [dict(reversed(list(r.items()))) for r in records[:3]]))
    edit("calibrated_sensor", calibrations)
    edit("log", lambda records: records[0].__setitem__("map_token", "only here"))
    edit("ego_pose", lambda records: records[3].__setitem__("translation", [int(records[3]["translation"][0]), 1.5, 0]))
    annotations_2d = json.loads((folder / "sample_annotation.json").read_text())[:6]
    boxes_2d = [{"token": f"{i:032x}", "sample_annotation_token": a["token"], "bbox_corners": [1, 2.5, 300, 400.25 + i],
                 "visibility_token": a["visibility_token"], "filename": f"samples/CAM_FRONT/{i}.jpg"}
                for i, a in enumerate(annotations_2d)]
    boxes_2d[3] = dict(reversed(list(boxes_2d[3].items())))
    (folder / "image_annotations.json").write_text(json.dumps(boxes_2d))  # the devkit loads it when present
    return root


@pytest.fixture(scope="session")
def layouts_out(layouts_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "layouts-out", layouts_root, SYNTH_VERSION)


@pytest.fixture(scope="session")
def extract_trainval_root(extract_root, tmp_path_factory) -> Path:
    """The real extract presented as `v1.0-trainval` (links, nothing copied): the devkit's evaluation and split
    functions accept only the official versions, and both scenes are in the official val split."""
    root = tmp_path_factory.mktemp("extract-trainval") / "data"
    root.mkdir()
    (root / "v1.0-trainval").symlink_to(extract_root / EXTRACT_VERSION, target_is_directory=True)
    for name in ("samples", "maps"):
        (root / name).symlink_to(extract_root / name, target_is_directory=True)
    return root


@pytest.fixture(scope="session")
def extract_trainval_out(extract_trainval_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "extract-trainval-out", extract_trainval_root, "v1.0-trainval")


@pytest.fixture(scope="session")
def synth_mapped_root(synth_root, tmp_path_factory) -> Path:
    """`synth_root` (linked) with map PNGs that hold a pattern (the generator writes blank 64x64 placeholders): a
    3000x3000 px prior map with driveable blobs, for map masks and the devkit's ego-centric map underlay."""
    import json

    import cv2
    import numpy as np

    root = tmp_path_factory.mktemp("synth-mapped") / "data"
    root.mkdir()
    for entry in synth_root.iterdir():
        if entry.name != "maps":
            (root / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    (root / "maps").mkdir()
    rng = np.random.default_rng(17)
    for record in json.loads((synth_root / SYNTH_VERSION / "map.json").read_text()):
        pattern = np.zeros((3000, 3000), dtype=np.uint8)
        for x, y, radius in zip(rng.integers(0, 3000, 60), rng.integers(0, 3000, 60), rng.integers(50, 400, 60)):
            cv2.circle(pattern, (int(x), int(y)), int(radius), 255, thickness=-1)
        cv2.imwrite(str(root / record["filename"]), pattern)
    return root
