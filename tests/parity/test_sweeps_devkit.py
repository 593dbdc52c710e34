"""`frames.sweeps.multisweep` = devkit `LidarPointCloud.from_file_multisweep` / `RadarPointCloud.from_file_multisweep`:
the same points in the same order (lidar to the float32 the devkit stores; radar, whose transforms are composed from
our stored matrices rather than pyquaternion's, to 1e-9 m), the same time lags, for 1 to 10 sweeps, from the start of
a scene (fewer sweeps there) to its end, with radar filters on and off, from the files and from lidar_points/."""

from __future__ import annotations

import numpy as np
import pytest

import nuparquet
from conftest import SYNTH_VERSION
from nuparquet.frames.sweeps import multisweep


@pytest.fixture(scope="module")
def nusc(synth_root, devkit):
    return devkit.NuScenes(SYNTH_VERSION, str(synth_root), verbose=False)


@pytest.fixture(scope="module")
def points_out(synth_root, tmp_path_factory):
    """synth_root converted with its lidar and radar points, sweeps included."""
    out = tmp_path_factory.mktemp("sweeps-out") / "out"
    nuparquet.convert(synth_root, SYNTH_VERSION, out, sensors=("lidar", "radar"), sweeps=True, workers=1)
    return out


@pytest.mark.parametrize("source", ["files", "points"])
@pytest.mark.parametrize("channel", ["LIDAR_TOP", "RADAR_FRONT", "RADAR_BACK_LEFT"])
def test_multisweep_equals_the_devkit(nusc, synth_out, points_out, source, channel, tmp_path):
    from nuscenes.utils.data_classes import LidarPointCloud, RadarPointCloud

    # "points": from lidar_points/ and radar_points/ alone: the sensor files are not where they are looked for
    ds = nuparquet.open(synth_out) if source == "files" else nuparquet.open(points_out,
                                                                           dataroot=tmp_path / "no-sensor-files")
    cls = LidarPointCloud if channel.startswith("LIDAR") else RadarPointCloud
    checked = 0
    for sample in nusc.sample[:3] + nusc.sample[-2:]:
        for nsweeps in (1, 3, 10):
            pc, times = cls.from_file_multisweep(nusc, sample, channel, "LIDAR_TOP", nsweeps=nsweeps)
            ours = multisweep(ds, sample["token"], channel, "LIDAR_TOP", nsweeps)
            assert ours.points.shape == pc.points.T.shape and ours.points.dtype == pc.points.dtype
            if cls is LidarPointCloud:
                np.testing.assert_array_max_ulp(ours.points, pc.points.T, maxulp=1)
                assert np.mean(ours.points == pc.points.T) > 0.999
            else:
                np.testing.assert_allclose(ours.points, pc.points.T, rtol=0, atol=1e-9)
            assert np.array_equal(ours.times_s, times[0])
            assert len(ours.tokens) == len(np.unique(times)) or nsweeps == 1
            checked += pc.points.shape[1]
    assert checked > (10000 if cls is LidarPointCloud else 100)


def test_radar_without_filters_keeps_every_return(nusc, synth_out):
    from nuscenes.utils.data_classes import RadarPointCloud

    ds = nuparquet.open(synth_out)
    sample = nusc.sample[4]
    RadarPointCloud.disable_filters()
    try:
        pc, _ = RadarPointCloud.from_file_multisweep(nusc, sample, "RADAR_FRONT", "LIDAR_TOP", nsweeps=4)
    finally:
        RadarPointCloud.default_filters()
    ours = multisweep(ds, sample["token"], "RADAR_FRONT", "LIDAR_TOP", 4, radar_filters=False)
    np.testing.assert_allclose(ours.points, pc.points.T, rtol=0, atol=1e-9)


def test_a_channel_without_a_keyframe_in_the_sample_is_named(synth_out):
    ds = nuparquet.open(synth_out)
    sample = ds.scan("tables/sample").head(1).collect()["token"][0]
    with pytest.raises(nuparquet.UsageError, match="has no CAM_NOPE keyframe"):
        multisweep(ds, sample, "CAM_NOPE")
    with pytest.raises(nuparquet.UsageError, match="nsweeps must be at least 1"):
        multisweep(ds, sample, "LIDAR_TOP", nsweeps=0)


def test_radar_default_filters_drop_the_returns_the_devkit_drops(synth_root, synth_out, devkit, tmp_path):
    """The generator's radar returns all pass the devkit's default filters; here a copy of the dataroot's tables,
    maps and RADAR_FRONT files marks some returns invalid, ambiguous or of an unknown dynamic property: multisweep's
    default (filters on) drops exactly those the devkit's `RadarPointCloud.from_file_multisweep` drops."""
    import shutil

    from nuscenes.utils.data_classes import RadarPointCloud

    root = tmp_path / "data"
    for part in synth_root.iterdir():  # the tables, maps and label folders the devkit opens; not the sensor files
        if part.is_dir() and part.name not in ("samples", "sweeps"):
            shutil.copytree(part, root / part.name)
    files = sorted({p for folder in ("samples", "sweeps") for p in (synth_root / folder / "RADAR_FRONT").glob("*.pcd")})
    marked = 0
    for path in files:
        data = path.read_bytes()
        head = data.index(b"DATA binary\n") + len(b"DATA binary\n")
        points = np.frombuffer(data[head:-1], dtype=_radar_dtype(data[:head])).copy()
        states = np.arange(len(points)) % 4
        points["invalid_state"][states == 1] = 4  # only 0 is kept
        points["ambig_state"][states == 2] = 1  # only 3 is kept
        points["dyn_prop"][states == 3] = 7  # 0..6 are kept
        marked += int((states > 0).sum())
        target = root / path.relative_to(synth_root)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data[:head] + points.tobytes() + data[-1:])
    nusc = devkit.NuScenes(SYNTH_VERSION, str(root), verbose=False)
    ds = nuparquet.open(synth_out, dataroot=root)
    kept = 0
    for sample in nusc.sample[2:5]:
        pc, times = RadarPointCloud.from_file_multisweep(nusc, sample, "RADAR_FRONT", "LIDAR_TOP", nsweeps=3)
        ours = multisweep(ds, sample["token"], "RADAR_FRONT", "LIDAR_TOP", 3)
        np.testing.assert_allclose(ours.points, pc.points.T, rtol=0, atol=1e-9)
        assert np.array_equal(ours.times_s, times[0])
        everything = multisweep(ds, sample["token"], "RADAR_FRONT", "LIDAR_TOP", 3, radar_filters=False)
        assert len(everything.points) > len(ours.points) > 0
        kept += len(ours.points)
    assert marked > 0 and kept > 0


def _radar_dtype(header: bytes) -> np.dtype:
    lines = dict(line.split(" ", 1) for line in header.decode("ascii").splitlines() if " " in line)
    names, sizes, kinds = lines["FIELDS"].split(), lines["SIZE"].split(), lines["TYPE"].split()
    return np.dtype([(n, f"<{k.lower()}{s}") for n, s, k in zip(names, sizes, kinds)])


def test_a_radar_file_whose_first_point_holds_a_nan_is_the_devkits_empty_cloud(synth_root, synth_out, tmp_path):
    """`frame_cloud` reading a radar frame from its file (synth_out has no radar_points/): a NaN in the first point
    is the devkit's sign of an empty file, and `RadarPointCloud.from_file` returns no point, filters on or off; a NaN
    in a later point keeps every point (the devkit's shape either way)."""
    import polars as pl
    from nuscenes.utils.data_classes import RadarPointCloud

    from nuparquet.frames.sweeps import frame_cloud

    ds = nuparquet.open(synth_out)
    assert "radar_points" not in ds.datasets  # the cloud is read from the file below
    row = ds.scan("frames").filter(pl.col("channel").cast(pl.String) == "RADAR_FRONT").head(1).collect() \
        .row(0, named=True)
    data = (synth_root / row["filename"]).read_bytes()
    head = data.index(b"DATA binary\n") + len(b"DATA binary\n")
    for nan_at in (0, 1):
        points = np.frombuffer(data[head:-1], dtype=_radar_dtype(data[:head])).copy()
        assert len(points) > 2
        points["ambig_state"], points["invalid_state"], points["dyn_prop"] = 3, 0, 1  # every filter passes
        points["vx"][nan_at] = np.nan
        path = tmp_path / str(nan_at) / row["filename"]
        path.parent.mkdir(parents=True)
        path.write_bytes(data[:head] + points.tobytes() + data[-1:])
        expected = RadarPointCloud.from_file(str(path)).points.T
        assert len(expected) == (0 if nan_at == 0 else len(points))
        for filters in (True, False):
            ours, names = frame_cloud(nuparquet.open(synth_out, dataroot=tmp_path / str(nan_at)), row, "radar",
                                      radar_filters=filters)
            assert ours.shape == expected.shape and len(names) == expected.shape[1], (nan_at, filters)
            np.testing.assert_array_equal(ours, expected)
