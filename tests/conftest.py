"""Shared fixtures: the real nuScenes extract (skipped cleanly when ../shared is absent), small synthetic
datasets, and their conversions. Conversions are session-scoped: every test reads them, none writes them."""

from __future__ import annotations

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


@pytest.fixture(scope="session")
def extract_root() -> Path:
    if not (EXTRACT_ROOT / EXTRACT_VERSION).is_dir():
        pytest.skip("real nuScenes extract not present (../shared/data/nuscenes-extract)")
    return EXTRACT_ROOT


@pytest.fixture(scope="session")
def extract_out(extract_root, tmp_path_factory) -> Path:
    from nuparquet.convert import convert

    out = tmp_path_factory.mktemp("extract") / "out"
    convert(extract_root, EXTRACT_VERSION, out)
    return out


@pytest.fixture(scope="session")
def extract_points_out(extract_root, tmp_path_factory) -> Path:
    """The real extract converted with its sensor points (lidar_points/, radar_points/), one process."""
    from nuparquet.convert import convert

    out = tmp_path_factory.mktemp("extract-points") / "out"
    convert(extract_root, EXTRACT_VERSION, out, sensors=("lidar", "radar"), jobs=1)
    return out


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

    root = tmp_path_factory.mktemp("synth") / "data"
    synthesize(root, scenes=2, samples_per_scene=6, with_images=True, with_lidar=True, seed=7, version=SYNTH_VERSION)
    return root


@pytest.fixture(scope="session")
def synth_out(synth_root, tmp_path_factory) -> Path:
    from nuparquet.convert import convert

    out = tmp_path_factory.mktemp("synth-out") / "out"
    convert(synth_root, SYNTH_VERSION, out)
    return out


@pytest.fixture(scope="session")
def devkit():
    """The nuscenes-devkit module (test-only reference implementation)."""
    return pytest.importorskip("nuscenes.nuscenes")


LYFT_RIG_VERSION = "v1.0-lyft-rig"


@pytest.fixture(scope="session")
def lyft_rig_root(tmp_path_factory) -> Path:
    """A synthetic dataset with a Lyft Level 5-like sensor set: seven cameras (CAM_FRONT_ZOOMED among them;
    1224x1024 images, the zoomed one 2048x864), three lidars (LIDAR_TOP, LIDAR_FRONT_LEFT, LIDAR_FRONT_RIGHT),
    no radar. One scene x 4 samples, with images and lidar files."""
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("lyft-rig") / "data"
    synthesize(root, scenes=1, samples_per_scene=4, with_images=True, with_lidar=True, seed=11,
               version=LYFT_RIG_VERSION, rig="lyft")
    return root


@pytest.fixture(scope="session")
def lyft_rig_out(lyft_rig_root, tmp_path_factory) -> Path:
    from nuparquet.convert import convert

    out = tmp_path_factory.mktemp("lyft-rig-out") / "out"
    convert(lyft_rig_root, LYFT_RIG_VERSION, out)
    return out


@pytest.fixture(scope="session")
def map_root(tmp_path_factory) -> Path:
    """6 scenes x 4 samples, tables only: four locations, two of them with two roads."""
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("map-synth") / "data"
    synthesize(root, scenes=6, samples_per_scene=4, seed=5, version=SYNTH_VERSION, with_can_bus=False)
    return root


@pytest.fixture(scope="session")
def map_out(map_root, tmp_path_factory) -> Path:
    from nuparquet.convert import convert

    out = tmp_path_factory.mktemp("map-out") / "out"
    convert(map_root, SYNTH_VERSION, out)
    return out


@pytest.fixture(scope="session")
def devkit_maps(map_root) -> dict:
    """{location: NuScenesMap} for every synthetic map (the reference)."""
    from nuscenes.map_expansion.map_api import NuScenesMap

    return {p.stem: NuScenesMap(str(map_root), p.stem) for p in sorted((map_root / "maps" / "expansion").glob("*.json"))}
