"""The one sensor reader (`ds.sensors`, `nuparquet.sensors.reader`) on an output converted without its points:
every frame read from its file under the dataroot, compared with the file read another way (numpy for the lidar's
float32 rows, the devkit's `RadarPointCloud.from_file` for the radar's PCD), the label files as the devkit reads
them, and the one rule for filenames that leave the dataroot."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import nuparquet
from nuparquet.errors import InputError, UsageError
from nuparquet.sensors.reader import inside


@pytest.fixture(scope="module")
def ds(lidarseg_out, lidarseg_root):
    return nuparquet.open(lidarseg_out, dataroot=lidarseg_root)


def _frame(ds, modality: str, key_frame: bool = True) -> dict:
    return (ds.scan("frames").filter((pl.col("modality") == modality) & (pl.col("is_key_frame") == key_frame))
            .sort("token").first().collect().row(0, named=True))


@pytest.mark.parametrize("filename, expected", [
    ("samples/LIDAR_TOP/a.pcd.bin", "samples/LIDAR_TOP/a.pcd.bin"), ("samples/../../x.bin", None),
    ("../x.bin", None), ("/etc/passwd", None), ("samples/..x/y.bin", "samples/..x/y.bin")])
def test_a_filename_leaving_the_dataroot_is_refused_and_only_that(tmp_path, ds, filename, expected):
    assert inside(tmp_path, filename) == (None if expected is None else tmp_path / expected)
    if expected is None:
        with pytest.raises(InputError, match=f"^{filename}: outside the dataroot, refused$"):
            ds.sensors.path(filename)
    else:
        assert ds.sensors.path(filename) == Path(ds.dataroot) / expected


def test_lidar_points_come_from_the_file_with_every_field(ds):
    row = _frame(ds, "lidar")
    assert ds.sensors.converted_columns("lidar") == []  # not converted: the file is the source
    assert ds.sensors.sensor_fields("lidar") == ["x", "y", "z", "intensity", "ring"]
    frame = ds.sensors.points(row["token"], row["filename"], "lidar")
    raw = np.fromfile(Path(ds.dataroot) / row["filename"], dtype=np.float32).reshape(-1, 5)
    assert frame.columns == ["x", "y", "z", "intensity", "ring"] and frame.height == len(raw) > 100
    np.testing.assert_array_equal(frame.to_numpy(), raw)
    assert ds.sensors.points(row["token"], row["filename"], "lidar", ["z", "x", "lidarseg_label"]).columns == ["z", "x"]


def test_radar_points_are_the_pcd_fields_the_devkit_reads_unfiltered(ds):
    from nuscenes.utils.data_classes import RadarPointCloud

    row = _frame(ds, "radar")
    frame = ds.sensors.points(row["token"], row["filename"], "radar")
    RadarPointCloud.disable_filters()
    try:
        pc = RadarPointCloud.from_file(str(Path(ds.dataroot) / row["filename"]))
    finally:
        RadarPointCloud.default_filters()
    assert frame.columns[:3] == ["x", "y", "z"] and len(frame.columns) == pc.points.shape[0]
    assert frame.height == pc.points.shape[1] > 0
    np.testing.assert_array_equal(frame.to_numpy().astype(np.float32).T, pc.points.astype(np.float32))


def test_lidar_with_labels_reads_the_label_file_the_table_names(ds):
    row = _frame(ds, "lidar")
    points, labels = ds.sensors.lidar(row["token"], row["filename"], labels="lidarseg")
    raw = np.fromfile(Path(ds.dataroot) / row["filename"], dtype=np.float32).reshape(-1, 5)
    np.testing.assert_array_equal(points, raw[:, :4])
    name = ds.scan("tables/lidarseg").filter(pl.col("sample_data_token") == row["token"]).collect()["filename"][0]
    expected = np.fromfile(Path(ds.dataroot) / name, dtype=np.uint8).astype(np.int64)
    assert labels.dtype == np.int64 and len(labels) == len(points)
    np.testing.assert_array_equal(labels, expected)
    np.testing.assert_array_equal(ds.sensors.label_file(row["token"], "lidarseg"), expected)


def test_panoptic_labels_are_the_npz_data_array_as_the_devkit_loads_it(ds):
    from nuscenes.utils.data_io import load_bin_file

    row = _frame(ds, "lidar")
    name = ds.scan("tables/panoptic").filter(pl.col("sample_data_token") == row["token"]).collect()["filename"][0]
    expected = load_bin_file(str(Path(ds.dataroot) / name), type="panoptic").astype(np.int64)
    assert (expected // 1000 > 0).any() and (expected % 1000 > 0).any()  # classes and instances, not all zero
    np.testing.assert_array_equal(ds.sensors.label_file(row["token"], "panoptic"), expected)


def test_labels_that_do_not_exist_are_refused_saying_why(ds, extract_out, extract_root):
    sweep = _frame(ds, "lidar", key_frame=False)
    with pytest.raises(UsageError, match=f"sample_data {sweep['token']} has no lidarseg labels \\(only lidar "
                                         "keyframes have them\\)"):
        ds.sensors.label_file(sweep["token"], "lidarseg")
    real = nuparquet.open(extract_out, dataroot=extract_root)  # the real extract holds no label tables
    lidar = _frame(real, "lidar")
    with pytest.raises(UsageError, match="has no panoptic labels \\(the dataroot had no panoptic.json when "
                                         "converted\\)"):
        real.sensors.label_file(lidar["token"], "panoptic")
    with pytest.raises(UsageError, match="has no lidarseg labels"):
        real.sensors.lidar(lidar["token"], lidar["filename"], labels="lidarseg")


def test_a_converted_frame_is_read_from_the_points_dataset_with_its_sensor_fields(synth_points_out, synth_root):
    """On an output converted with its points the reader takes the frame from `lidar_points/` / `radar_points/`:
    by default every sensor field the dataset stores (no frame columns, no filter flag), the same rows and
    values as `ds.points` / `ds.radar_points`; the file under the dataroot is not needed."""
    from nuparquet.frames.points import FRAME_COLUMNS

    converted = nuparquet.open(synth_points_out, dataroot=synth_root)
    for modality, read in (("lidar", converted.points), ("radar", converted.radar_points)):
        row = _frame(converted, modality)
        stored = converted.scan(f"{modality}_points").collect_schema().names()
        fields = [c for c in stored if c not in FRAME_COLUMNS and c != "passes_default_filters"]
        assert fields and converted.sensors.sensor_fields(modality) == fields
        frame = converted.sensors.points(row["token"], "samples/not-there.bin", modality)  # no file read
        assert frame.columns == fields
        assert frame.equals(read(row["token"], columns=fields))


@pytest.mark.parametrize("modality, what", [("camera", "the camera images"), ("lidar", "the lidar points"),
                                            ("radar", "the radar points")])
def test_a_missing_file_says_which_data_of_which_frame_and_pickles_whole(ds, tmp_path, modality, what):
    """The refusal names the kind of data (images for cameras, points for the rest), the frame and the file; and it
    crosses a process boundary whole (a DataLoader worker's exception is pickled to the main process)."""
    import pickle

    from nuparquet.sensors.reader import MissingSensorData

    row = _frame(ds, modality)
    with pytest.raises(MissingSensorData) as caught:
        ds.sensors.file(row["token"], row["filename"] + ".gone", modality)
    message = str(caught.value)
    assert f"({what} of sample_data {row['token']}" in message and row["filename"] + ".gone" in message
    assert caught.value.args == (message,)  # as any exception holds its message
    back = pickle.loads(pickle.dumps(caught.value))
    assert type(back) is MissingSensorData and str(back) == message and back.path == caught.value.path
    assert isinstance(back, FileNotFoundError) and isinstance(back, InputError)


def test_labels_alone_are_the_label_files_from_the_files_and_from_lidar_points(ds, labelled_out, labelled_root,
                                                                            tmp_path):
    """`labels(token, kind)`: the frame's ground-truth labels without its points, from lidar_points/ when the frame
    is there with them and from the label file otherwise; the same int64 values either way."""
    converted = nuparquet.open(labelled_out, dataroot=labelled_root)
    assert "lidarseg_label" in converted.sensors.converted_columns("lidar")
    assert not ds.sensors.converted_columns("lidar")
    for kind in ("lidarseg", "panoptic"):
        row = _frame(converted, "lidar")
        from_points = converted.sensors.labels(row["token"], kind)
        from_file = converted.sensors.label_file(row["token"], kind)
        assert from_points.dtype == from_file.dtype == np.int64 and len(from_points) > 0
        np.testing.assert_array_equal(from_points, from_file)
        _, with_points = converted.sensors.lidar(row["token"], row["filename"], labels=kind)  # lidar_points/ too
        assert with_points.dtype == np.int64
        np.testing.assert_array_equal(with_points, from_file)
        row = _frame(ds, "lidar")
        np.testing.assert_array_equal(ds.sensors.labels(row["token"], kind), ds.sensors.label_file(row["token"], kind))
    # from lidar_points/ alone: a dataroot without the label files is never read
    no_files = nuparquet.open(labelled_out, dataroot=tmp_path)
    row = _frame(no_files, "lidar")
    np.testing.assert_array_equal(no_files.sensors.labels(row["token"], "lidarseg"),
                                  converted.sensors.label_file(row["token"], "lidarseg"))
