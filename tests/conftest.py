"""Shared fixtures: the real nuScenes extract (skipped cleanly when ../shared is absent), small synthetic
datasets, and their conversions. Conversions are session-scoped: every test reads them, none writes them."""

from __future__ import annotations

import os
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


def _shared_present() -> bool:
    return (EXTRACT_ROOT / EXTRACT_VERSION).is_dir()


def pytest_collection_modifyitems(config, items):
    for item in items:
        names = getattr(item, "fixturenames", ())
        if "devkit" in names or Path(str(item.path)).is_relative_to(PARITY_DIR):
            item.add_marker(pytest.mark.devkit)
        if "extract_root" in names:
            item.add_marker(pytest.mark.real)


def pytest_runtest_logreport(report):
    if report.skipped and not hasattr(report, "wasxfail") and ("devkit" in report.keywords or "real" in report.keywords):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        _parity_skips.append(f"{report.nodeid}: {reason}")


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session, exitstatus):
    if hasattr(session.config, "workerinput"):  # an xdist worker: its reports reach the controller
        return
    if _parity_skips and _shared_present() and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if _parity_skips and _shared_present():
        terminalreporter.section("parity tests skipped although ../shared is present", red=True)
        for line in _parity_skips:
            terminalreporter.write_line(line, red=True)
        terminalreporter.write_line(f"error: {len(_parity_skips)} parity/devkit test(s) skipped: the run fails "
                                    "(they may skip only where ../shared is absent)", red=True)


@pytest.fixture(scope="session")
def extract_root() -> Path:
    if not (EXTRACT_ROOT / EXTRACT_VERSION).is_dir():
        pytest.skip("real nuScenes extract not present (../shared/data/nuscenes-extract)")
    return EXTRACT_ROOT


@pytest.fixture(scope="session")
def extract_out(extract_root, tmp_path_factory) -> Path:
    return converted(tmp_path_factory, "extract", extract_root, EXTRACT_VERSION)


def generated_root(tmp_path_factory, name: str, make) -> Path:
    """A dataroot written by `make(root)` (the generator): in a fresh temporary directory, or, when
    NUPARQUET_TEST_CACHE names a directory (the mutation runs, which start pytest once per mutant), made once
    there and reused. The generator is deterministic and never mutated, so the cache cannot go stale within a run."""
    cache = os.environ.get("NUPARQUET_TEST_CACHE")
    if not cache:
        root = tmp_path_factory.mktemp(name) / "data"
        make(root)
        return root
    root = Path(cache) / name / "data"
    if not (root.parent / ".complete").exists():
        make(root)
        (root.parent / ".complete").touch()
    return root


def converted(tmp_path_factory, name: str, root: Path, version: str, **options) -> Path:
    """`nuparquet convert` of `root`/`version` into a fresh temporary OUT (the session's converted fixtures)."""
    from nuparquet.convert import convert

    out = tmp_path_factory.mktemp(name) / "out"
    convert(root, version, out, **options)
    return out


@pytest.fixture(scope="session")
def extract_points_out(extract_root, tmp_path_factory) -> Path:
    """The real extract converted with its sensor points (lidar_points/, radar_points/), one process."""
    return converted(tmp_path_factory, "extract-points", extract_root, EXTRACT_VERSION, sensors=("lidar", "radar"),
                     jobs=1)


@pytest.fixture(scope="session")
def labelled_root(tmp_path_factory) -> Path:
    """2 scenes x 3 samples with lidar/radar keyframes and sweeps and lidarseg/panoptic labels, no CAN bus."""
    from nuparquet.synth import synthesize

    return synthesize(tmp_path_factory.mktemp("labelled") / "data", scenes=2, samples_per_scene=3, with_lidar=True,
                      seed=11, version=SYNTH_VERSION, with_can_bus=False)


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
def devkit():
    """The nuscenes-devkit module (test-only reference implementation). Not installed is a failure, never a
    skip: `make test` installs it, and a parity test that silently stops running hides regressions."""
    import nuscenes.nuscenes

    return nuscenes.nuscenes


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
def map_root(tmp_path_factory) -> Path:
    """6 scenes x 4 samples, tables only: four locations, two of them with two roads."""
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("map-synth") / "data"
    synthesize(root, scenes=6, samples_per_scene=4, seed=5, version=SYNTH_VERSION, with_can_bus=False)
    return root


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


# --- nuparquet.devkit: the devkit's NuScenes served from the Parquet (tests/parity/test_devkit_*.py) ---------------

@pytest.fixture(scope="session")
def labelled_out(labelled_root, tmp_path_factory) -> Path:
    """The labelled set converted with its lidar and radar keyframe points and its lidarseg/panoptic tables."""
    return converted(tmp_path_factory, "labelled-out", labelled_root, SYNTH_VERSION, sensors=("lidar", "radar"), jobs=1)


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
