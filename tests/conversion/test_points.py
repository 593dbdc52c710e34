"""`convert --sensors lidar,radar` on synthetic data with lidarseg/panoptic labels: the point and label columns
against the files read another way (numpy), the same bytes whatever --jobs, `ds.points` reading one frame, and
clean problems for broken sensor and label files."""

from __future__ import annotations

import json
import shutil

import numpy as np
import polars as pl
import pyarrow.parquet as pq
import pytest

from conftest import SYNTH_VERSION
from nuparquet.conversion import convert
from nuparquet.problems import ProblemsFound


@pytest.fixture(scope="module")
def labelled_out(labelled_root, tmp_path_factory):
    out = tmp_path_factory.mktemp("labelled-out") / "out"
    convert(labelled_root, SYNTH_VERSION, out, sensors=("lidar", "radar"), sweeps=True, workers=1)
    return out


def _lidar_frames(root, keyframes_only: bool) -> list[dict]:
    sample_data = json.loads((root / SYNTH_VERSION / "sample_data.json").read_text())
    return [r for r in sample_data if r["filename"].endswith(".pcd.bin") and (r["is_key_frame"] or not keyframes_only)]


def test_lidar_points_and_labels_equal_the_files(labelled_root, labelled_out):
    lidarseg = {r["sample_data_token"]: r["filename"] for r in json.loads((labelled_root / SYNTH_VERSION / "lidarseg.json").read_text())}
    panoptic = {r["sample_data_token"]: r["filename"] for r in json.loads((labelled_root / SYNTH_VERSION / "panoptic.json").read_text())}
    table = pl.read_parquet(str(labelled_out / "lidar_points" / "*.parquet")).with_columns(pl.col("sample_data_token").cast(pl.String))
    by_token = table.partition_by("sample_data_token", as_dict=True)
    frames = _lidar_frames(labelled_root, keyframes_only=False)
    assert len(by_token) == len(frames) and any(not f["is_key_frame"] for f in frames)
    labelled = 0
    for f in frames:
        rows = by_token[(f["token"],)]
        raw = np.fromfile(labelled_root / f["filename"], dtype=np.float32).reshape(-1, 5)
        stored = np.stack([rows[c].cast(pl.Float32).to_numpy() for c in ("x", "y", "z", "intensity", "ring")], axis=1)
        assert np.array_equal(stored.view(np.uint32), raw.view(np.uint32)), f["filename"]
        assert rows["is_key_frame"].unique().to_list() == [f["is_key_frame"]]
        assert rows["timestamp"].unique().to_list() == [f["timestamp"]]
        if f["token"] in lidarseg:
            labelled += 1
            assert np.array_equal(rows["lidarseg_label"].to_numpy(), np.fromfile(labelled_root / lidarseg[f["token"]], np.uint8))
            assert np.array_equal(rows["panoptic_label"].to_numpy(), np.load(labelled_root / panoptic[f["token"]])["data"])
        else:  # sweeps have no label files: nulls, not zeros
            assert rows["lidarseg_label"].null_count() == rows["panoptic_label"].null_count() == rows.height
    assert labelled == len(lidarseg) == 6  # every keyframe of LIDAR_TOP


def test_points_are_sorted_by_scene_channel_timestamp_point_index(labelled_out):
    for dataset in ("lidar_points", "radar_points"):
        table = pl.read_parquet(str(labelled_out / dataset / "*.parquet"),
                                columns=["scene_name", "channel", "timestamp", "point_index"]).with_columns(
            pl.col("scene_name", "channel").cast(pl.String))
        assert table.equals(table.sort("scene_name", "channel", "timestamp", "point_index")), dataset


def test_output_is_byte_identical_whatever_jobs(labelled_root, labelled_out, tmp_path):
    out = tmp_path / "jobs2"
    convert(labelled_root, SYNTH_VERSION, out, sensors=("lidar", "radar"), sweeps=True, workers=2)
    for dataset in ("lidar_points", "radar_points"):
        ours = sorted(p.name for p in (labelled_out / dataset).glob("*.parquet"))
        assert ours == sorted(p.name for p in (out / dataset).glob("*.parquet")) and len(ours) == 2  # one per scene
        for name in ours:
            assert (labelled_out / dataset / name).read_bytes() == (out / dataset / name).read_bytes(), (dataset, name)


def test_ds_points_returns_one_frame_a_list_and_a_scene_as_the_files_hold_them(labelled_root, labelled_out):
    import nuparquet

    ds = nuparquet.open(labelled_out)
    frames = _lidar_frames(labelled_root, keyframes_only=False)
    raw = {f["token"]: np.fromfile(labelled_root / f["filename"], dtype=np.float32).reshape(-1, 5) for f in frames}
    one = frames[7]["token"]
    points = ds.points(one)
    assert points.dtype == np.float32 and np.array_equal(points, raw[one])
    pair = [frames[9]["token"], frames[2]["token"]]  # the order asked for, not the dataset's
    assert np.array_equal(ds.points(pair), np.concatenate([raw[t] for t in pair]))
    scene_tokens = sorted((f for f in frames if f["token"] in raw), key=lambda f: f["timestamp"])
    scene = pl.scan_parquet(str(labelled_out / "frames" / "*.parquet")).filter(pl.col("token") == one).select("scene_name").collect().item()
    in_scene = set(pl.scan_parquet(str(labelled_out / "frames" / "*.parquet")).filter(pl.col("scene_name") == scene)
                   .select("token").collect()["token"].to_list())
    expected = np.concatenate([raw[f["token"]] for f in scene_tokens if f["token"] in in_scene])
    assert np.array_equal(ds.points(scene=scene), expected)
    labels = ds.points(one, columns=["lidarseg_label"])
    assert labels.height == len(raw[one])


def test_ds_points_of_an_empty_token_list_are_no_points_typed_as_the_files(labelled_root, labelled_out):
    """`ds.points([])` (a list of frames that happens to be empty, e.g. a filter that kept none): no points, of the
    same array shape and dtype as a frame's, not Arrow's "Must pass at least one table"; radar and columns alike."""
    import nuparquet
    from nuparquet.sources.points import read_radar_pcd

    ds = nuparquet.open(labelled_out)
    lidar = ds.points([])
    assert lidar.shape == (0, 5) and lidar.dtype == np.float32
    radar_file = next(f["filename"] for f in json.loads((labelled_root / SYNTH_VERSION / "sample_data.json").read_text())
                      if f["filename"].endswith(".pcd"))
    radar = ds.radar_points([])
    assert radar.shape == (0, len(read_radar_pcd(labelled_root / radar_file).dtype.names)) and radar.dtype == np.float64
    for dataset, read in (("lidar_points", ds.points), ("radar_points", ds.radar_points)):
        stored = pl.read_parquet(next((labelled_out / dataset).glob("*.parquet")), n_rows=1)
        frame = read([], columns=["x", "timestamp", "sample_data_token"])
        assert frame.height == 0 and frame.schema == stored.select("x", "timestamp", "sample_data_token").schema


def test_ds_points_chooses_every_row_group_holding_the_frame_and_not_all(labelled_out):
    import nuparquet

    ds = nuparquet.open(labelled_out)
    index = ds._points_index("lidar_points")
    token = pl.read_parquet(str(labelled_out / "lidar_points" / "part-00001.parquet"), columns=["sample_data_token"])[
        "sample_data_token"].cast(pl.String)[0]
    wanted = index.groups_for_tokens([token])
    holding = np.array([token in set(pq.ParquetFile(index.paths[f]).read_row_group(int(g), columns=["sample_data_token"])
                                     .column(0).to_pylist()) for f, g in zip(index.file, index.group)])
    assert holding.sum() == 1  # a frame never spans two row groups
    assert (wanted >= holding).all() and wanted.sum() < wanted.size  # (one exactly for real 35k-point frames)


def test_radar_points_keep_every_pcd_field_typed_as_its_header(labelled_root, labelled_out):
    from nuparquet.sources.points import read_radar_pcd

    sample_data = json.loads((labelled_root / SYNTH_VERSION / "sample_data.json").read_text())
    first = next(r for r in sample_data if r["filename"].endswith(".pcd"))
    header = read_radar_pcd(labelled_root / first["filename"]).dtype
    schema = pq.read_schema(next((labelled_out / "radar_points").glob("*.parquet")))
    pcd = [f for f in schema if f.name in header.names]
    assert [f.name for f in pcd] == list(header.names)
    assert [f.type.to_pandas_dtype() for f in pcd] == [header[n].type for n in header.names]


# -- broken inputs -------------------------------------------------------------------------------------------------

@pytest.fixture()
def small_root(labelled_root, tmp_path):
    root = tmp_path / "data"
    shutil.copytree(labelled_root, root)
    return root


def _first(root, table: str) -> dict:
    return json.loads((root / SYNTH_VERSION / f"{table}.json").read_text())[0]


def _problems(root, tmp_path, **options) -> str:
    out = tmp_path / "broken-out"
    with pytest.raises(ProblemsFound) as info:
        convert(root, SYNTH_VERSION, out, sensors=("lidar", "radar"), workers=1, **options)
    assert not out.exists() and not list(tmp_path.glob(".broken-out*"))  # nothing half-written is left
    return str(info.value)


def test_truncated_pcd_bin_is_a_problem_naming_the_file(small_root, tmp_path):
    name = _lidar_frames(small_root, keyframes_only=True)[1]["filename"]
    data = (small_root / name).read_bytes()
    (small_root / name).write_bytes(data[:-6])
    message = _problems(small_root, tmp_path)
    assert name in message and "not a whole number of 5-float32 points" in message


def test_a_pcd_bin_of_whole_floats_but_not_whole_points_is_a_problem_naming_the_file(small_root, tmp_path):
    """8 bytes short: still a whole number of float32 values (a reader checking only that would reshape garbage
    into shifted points), not a whole number of 20-byte points."""
    name = _lidar_frames(small_root, keyframes_only=True)[1]["filename"]
    data = (small_root / name).read_bytes()
    assert len(data) % 20 == 0
    (small_root / name).write_bytes(data[:-8])
    message = _problems(small_root, tmp_path)
    assert name in message and f"{len(data) - 8} bytes is not a whole number of 5-float32 points" in message


def test_read_lidar_bin_takes_only_whole_points_of_the_given_width(tmp_path):
    from nuparquet.sources.points import PointFileError, read_lidar_bin

    path = tmp_path / "x.pcd.bin"
    np.arange(28, dtype="<f4").tofile(path)  # 7 points of 4 values, or 5.6 points of 5
    assert read_lidar_bin(path, 4).shape == (7, 4)
    np.testing.assert_array_equal(read_lidar_bin(path, 4)[1], [4, 5, 6, 7])
    with pytest.raises(PointFileError, match=r"x\.pcd\.bin: 112 bytes is not a whole number of 5-float32 points"):
        read_lidar_bin(path)


def test_pcd_with_an_unexpected_header_is_a_problem_naming_the_file(small_root, tmp_path):
    sample_data = json.loads((small_root / SYNTH_VERSION / "sample_data.json").read_text())
    name = next(r["filename"] for r in sample_data if r["filename"].endswith(".pcd") and r["is_key_frame"])
    data = (small_root / name).read_bytes()
    (small_root / name).write_bytes(data.replace(b"DATA binary", b"DATA ascii", 1))
    message = _problems(small_root, tmp_path)
    assert name in message and "DATA 'ascii' is not supported" in message
    (small_root / name).write_bytes(data.replace(b"\nCOUNT 1 1 1", b"\nCOUNT 2 1 1", 1))
    assert "COUNT" in _problems(small_root, tmp_path)


def test_label_count_mismatch_names_both_files(small_root, tmp_path):
    record = _first(small_root, "lidarseg")
    labels = np.fromfile(small_root / record["filename"], np.uint8)
    labels[:-1].tofile(small_root / record["filename"])
    sensor = next(f["filename"] for f in _lidar_frames(small_root, True) if f["token"] == record["sample_data_token"])
    message = _problems(small_root, tmp_path)
    assert record["filename"] in message and sensor in message
    assert f"{labels.size - 1} labels but {sensor} has {labels.size} points" in message


def test_missing_label_file_names_both_files(small_root, tmp_path):
    record = _first(small_root, "panoptic")
    (small_root / record["filename"]).unlink()
    sensor = next(f["filename"] for f in _lidar_frames(small_root, True) if f["token"] == record["sample_data_token"])
    message = _problems(small_root, tmp_path)
    assert record["filename"] in message and sensor in message and "missing" in message


def test_missing_sensor_files_are_listed_and_warned_once_or_an_error_with_strict(small_root, tmp_path):
    frames = _lidar_frames(small_root, keyframes_only=True)
    gone = sorted(f["filename"] for f in frames[:2])
    for name in gone:
        (small_root / name).unlink()
    manifest = convert(small_root, SYNTH_VERSION, tmp_path / "out", sensors=("lidar",), workers=1)
    entry = manifest["datasets"]["lidar_points"]
    assert sorted(entry["missing_files"]) == gone and entry["frames"] == len(frames) - 2
    warnings = [w for w in manifest["warnings"] if "lidar_points" in w]
    assert len(warnings) == 1 and "2 sensor file(s) missing" in warnings[0]
    message = _problems(small_root, tmp_path, strict=True)
    assert all(name in message for name in gone)


def test_stats_gains_lidarseg_sections_and_a_chart_when_labels_were_converted(labelled_out, tmp_path):
    import nuparquet
    from nuparquet.rendering.pictures.charts import write_plots
    from nuparquet.queries.sections import default_sections

    labelled = nuparquet.open(labelled_out)
    assert {"lidarseg", "panoptic"} <= set(default_sections(labelled))
    paths = write_plots(labelled, tmp_path / "plots")
    chart = tmp_path / "plots" / "lidarseg_points_per_class.png"
    assert chart in paths and chart.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_stats_has_no_lidarseg_sections_for_points_without_labels(extract_points_out):
    import nuparquet
    from nuparquet.queries.sections import default_sections

    unlabelled = nuparquet.open(extract_points_out)  # real lidar points, no label files
    assert "lidar_points" in unlabelled.datasets and not {"lidarseg", "panoptic"} & set(default_sections(unlabelled))


def test_bad_sensor_options_are_usage_errors(labelled_root, tmp_path, capsys):
    from nuparquet.cli.main import main

    for flags, message in ((["--sensors", "lidar,camera"], "--sensors takes lidar, radar"),
                           (["--sensors", "lidar", "--jobs", "-1"], "--workers must be"),
                           (["--sensors", "lidar", "--lidar-columns", "7"], "--lidar-columns must be 4 or 5")):
        code = main(["convert", str(labelled_root), "--version", SYNTH_VERSION, "--out", str(tmp_path / "o"), *flags])
        assert code == 2 and message in capsys.readouterr().err
        assert not (tmp_path / "o").exists()


def test_select_points_of_a_scene_and_one_channel_with_every_column_by_default(labelled_root, labelled_out):
    """`select_points(index, scene=..., channel=...)`: every point of that channel's frames in the scene, in dataset
    (time) order, each frame as the .pcd file holds it; without `columns` every column of the dataset; an unknown
    column is refused by name."""
    import nuparquet
    from nuparquet.errors import UsageError
    from nuparquet.frames.points import select_points
    from nuparquet.sources.points import read_radar_pcd

    ds = nuparquet.open(labelled_out)
    index = ds._points_index("radar_points")
    frames = (pl.read_parquet(labelled_out / "frames").filter(pl.col("modality") == "radar")
              .sort("scene_name", "channel", "timestamp"))
    scene = frames["scene_name"][0]
    channels = sorted(set(frames.filter(pl.col("scene_name") == scene)["channel"]))
    assert len(channels) > 1  # the filter has other channels' points to leave out
    for channel in channels[:2]:
        mine = frames.filter((pl.col("scene_name") == scene) & (pl.col("channel") == channel))
        expected = np.concatenate([read_radar_pcd(labelled_root / f)["x"] for f in mine["filename"]])
        got = select_points(index, scene=scene, channel=channel)
        assert got.column_names == list(index.fields) == pq.read_schema(next((labelled_out / "radar_points")
                                                                              .glob("*.parquet"))).names
        assert set(got.column("channel").to_pylist()) == {channel}
        assert np.array_equal(got.column("x").to_numpy(), expected)
        assert got.column("sample_data_token").to_pylist() == [t for t, f in zip(mine["token"], mine["filename"])
                                                               for _ in range(len(read_radar_pcd(labelled_root / f)))]
    whole = select_points(index, scene=scene, columns=["channel"])
    assert sorted(set(whole.column("channel").to_pylist())) == channels
    with pytest.raises(UsageError, match=r"^no column 'nope', 'z2' \(columns: sample_data_token, "):
        select_points(index, scene=scene, columns=["x", "nope", "z2"])


def test_select_points_of_a_scene_no_row_group_holds_is_empty_with_the_datasets_columns(labelled_out):
    """A scene name no row group's scene range reaches (before the first scene, between the two, after the last;
    each scene has its own part file): no row group is read, and the answer is an empty table of the asked columns
    typed as the Parquet files type them."""
    import nuparquet
    from nuparquet.frames.points import select_points

    ds = nuparquet.open(labelled_out)
    for dataset in ("lidar_points", "radar_points"):
        index = ds._points_index(dataset)
        stored = pq.read_schema(next((labelled_out / dataset).glob("*.parquet")))
        for columns in (None, ["x", "timestamp", "channel"]):
            names = columns or stored.names
            for scene in ("scene-0000", "scene-0001-not", "scene-9999"):
                got = select_points(index, scene=scene, columns=columns)
                assert got.num_rows == 0 and got.column_names == names, (dataset, scene)
                assert [f.type for f in got.schema] == [stored.field(n).type for n in names], (dataset, scene)


def test_pcd_headers_with_an_unknown_line_or_lines_missing_are_refused_naming_both():
    from nuparquet.sources.points import PointFileError, read_pcd_header

    good = ("VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
            "POINTS 1\nDATA binary\n")
    assert read_pcd_header("radar.pcd", good.encode()).data_offset == len(good)  # the well-formed header reads
    for header, reason in (
            (good.replace("VIEWPOINT", "COLOR"), "unexpected PCD header line 'COLOR' (expected one of VERSION, FIELDS, "
                                                 "SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT, POINTS, DATA)"),
            (good.replace("SIZE 4 4\nTYPE F F\n", ""), "PCD header lacks SIZE, TYPE")):
        with pytest.raises(PointFileError) as error:
            read_pcd_header("radar.pcd", header.encode())
        assert (error.value.path, error.value.reason) == ("radar.pcd", reason)


def test_pcd_headers_that_disagree_end_early_or_name_an_unknown_type_are_refused_naming_the_file():
    """Each header problem is a PointFileError naming the file (its `path`) and the problem, not a TypeError or a
    bare parse error; a header without HEIGHT or POINTS is the unorganised cloud those lines would state (HEIGHT 1,
    POINTS = WIDTH): the reader takes a missing HEIGHT as 1 and a missing POINTS as WIDTH x HEIGHT."""
    from nuparquet.sources.points import PointFileError, read_pcd_header

    good = ("VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
            "POINTS 3\nDATA binary\n")
    stated = read_pcd_header("radar.pcd", good.encode())
    assert (stated.fields, stated.points, stated.dtype) == (("x", "y"), 3, np.dtype([("x", "<f4"), ("y", "<f4")]))
    for unstated in (good.replace("HEIGHT 1\n", ""), good.replace("POINTS 3\n", ""),
                     good.replace("HEIGHT 1\n", "").replace("POINTS 3\n", "")):
        header = read_pcd_header("radar.pcd", unstated.encode())
        assert (header.fields, header.points, header.dtype, header.data_offset) == \
            (stated.fields, stated.points, stated.dtype, len(unstated))
    for header, reason in (
            (good.removesuffix("DATA binary\n"), "PCD header has no DATA line (not a PCD v0.7 file, or truncated)"),
            (good.replace("SIZE 4 4", "SIZE 4"), "PCD header has 2 FIELDS but 1 SIZE, 2 TYPE and 2 COUNT values"),
            (good.replace("SIZE 4 4", "SIZE 4 3"), "PCD SIZE/TYPE 4 3 / F F or WIDTH/HEIGHT/POINTS is not a supported "
                                                   "combination")):
        with pytest.raises(PointFileError) as error:
            read_pcd_header("radar.pcd", header.encode())
        assert (error.value.path, error.value.reason) == ("radar.pcd", reason)


def test_a_radar_pcd_whose_first_point_has_a_nan_passes_no_filter_as_the_devkit_reads_it_empty(tmp_path):
    """The devkit's `RadarPointCloud.from_file` returns an empty cloud when the first point holds a NaN (its sign of
    an empty file), whatever the states; a NaN in a later point does not empty it."""
    from nuscenes.utils.data_classes import RadarPointCloud

    from nuparquet.sources.points import passes_default_filters, read_radar_pcd
    from nuparquet.synth.sensors import _RADAR_DTYPE, _RADAR_HEADER

    for nan_at in (0, 1):
        points = np.zeros(3, dtype=_RADAR_DTYPE)
        points["x"] = [1.0, 2.0, 3.0]
        points["ambig_state"], points["invalid_state"], points["dyn_prop"] = 3, 0, 1  # every filter passes
        points["vx"][nan_at] = np.nan
        path = tmp_path / f"nan-{nan_at}.pcd"
        path.write_bytes(_RADAR_HEADER.format(n=3).encode("ascii") + points.tobytes() + b"\n")
        expected = RadarPointCloud.from_file(str(path)).points.shape[1]
        assert int(passes_default_filters(read_radar_pcd(path)).sum()) == expected == (0 if nan_at == 0 else 3)


@pytest.mark.parametrize("data, shape", [(np.zeros((3, 1), np.uint16), "uint16 of shape (3, 1)"),
                                         (np.zeros(3, np.float32), "float32 of shape (3,)")])
def test_panoptic_labels_not_one_integer_per_point_are_refused(tmp_path, data, shape):
    from nuparquet.sources.points import PointFileError, read_panoptic_npz

    path = tmp_path / "labels.npz"
    np.savez_compressed(path, data=data)
    with pytest.raises(PointFileError) as error:
        read_panoptic_npz(path)
    assert error.value.reason == f"panoptic 'data' is {shape}, not one integer per point"
    np.savez_compressed(path, data=np.array([0, 1001, 65535], np.int64))
    assert read_panoptic_npz(path).tolist() == [0, 1001, 65535]


@pytest.mark.parametrize("keep_going", [False, True])
def test_scenes_whose_point_task_raises_are_named_and_keep_going_names_every_one(small_root, tmp_path, keep_going):
    """A lidar keyframe that is a folder, in each of the two scenes: reading it raises IsADirectoryError (no problem
    the reader collects), so the scene's task fails. The conversion stops naming the first scene; with the engine's
    keep_going (a library option: `convert(..., keep_going=True)`) both scenes run and both are named. Nothing is
    left either way. (keep_going used to end in an AttributeError from the failed scene's missing summary.)"""
    from nuparquet.engine import UnitsFailed

    samples = {s["token"]: s for s in json.loads((small_root / SYNTH_VERSION / "sample.json").read_text())}
    scenes = {s["token"]: s["name"] for s in json.loads((small_root / SYNTH_VERSION / "scene.json").read_text())}
    broken: dict[str, str] = {}
    for frame in _lidar_frames(small_root, keyframes_only=True):
        broken.setdefault(scenes[samples[frame["sample_token"]]["scene_token"]], frame["filename"])
    assert sorted(broken) == ["scene-0001", "scene-0002"]
    for name in broken.values():
        (small_root / name).unlink()
        (small_root / name).mkdir()
    out = tmp_path / "out"
    with pytest.raises(UnitsFailed) as failed:
        convert(small_root, SYNTH_VERSION, out, sensors=("lidar",), workers=1, keep_going=keep_going)
    named = sorted(f.name for f in failed.value.failures)
    assert named == (sorted(broken) if keep_going else ["scene-0001"])
    for scene in named:
        assert f"{scene}: IsADirectoryError" in str(failed.value) and broken[scene].split("/")[-1] in str(failed.value)
    assert ("the other units finished" in str(failed.value)) == keep_going
    assert not out.exists() and not list(tmp_path.glob(".out*"))


def _pcd(tmp_path, name: str, header_lines: list[str], points: np.ndarray):
    path = tmp_path / name
    path.write_bytes(("\n".join(header_lines) + "\n").encode() + points.tobytes())
    return path


def test_a_pcd_header_without_count_has_one_value_per_field_as_the_pcd_format_says(tmp_path):
    """PCD v0.7: COUNT is optional and defaults to 1 per field; the same points with and without the line."""
    from nuparquet.sources.points import read_radar_pcd

    points = np.array([(1.5, -2.0, 0.25), (10.0, 3.5, -1.0)], dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    head = ["# .PCD v0.7 - Point Cloud Data file format", "VERSION 0.7", "FIELDS x y z", "SIZE 4 4 4", "TYPE F F F"]
    tail = ["WIDTH 2", "HEIGHT 1", "VIEWPOINT 0 0 0 1 0 0 0", "POINTS 2", "DATA binary"]
    with_count = read_radar_pcd(_pcd(tmp_path, "a.pcd", [*head, "COUNT 1 1 1", *tail], points))
    without = read_radar_pcd(_pcd(tmp_path, "b.pcd", [*head, *tail], points))
    assert without.dtype.names == ("x", "y", "z") and with_count.dtype.names == ("x", "y", "z")
    for name in ("x", "y", "z"):
        np.testing.assert_array_equal(without[name], points[name])
        np.testing.assert_array_equal(with_count[name], points[name])


def test_a_panoptic_file_that_is_not_an_npz_archive_is_a_problem_naming_it(tmp_path):
    from nuparquet.sources.points import PointFileError, read_panoptic_npz

    path = tmp_path / "labels_panoptic.npz"
    path.write_bytes(b"not a zip archive at all")
    with pytest.raises(PointFileError, match="not a readable .npz file") as raised:
        read_panoptic_npz(path)
    assert raised.value.path == str(path)


def test_the_scene_tasks_counted_before_the_run_are_the_scenes_with_frames_of_the_modality(labelled_root, tmp_path):
    """`Builder.units` of the points builders (the progress total, counted before any dataset is written): the
    scenes that have a frame of the modality, keyframes only unless --sweeps. Scene 2 keeps no lidar frame and only
    radar sweeps (its radar keyframes made sweeps), so each count tells the modality and the keyframe rule apart;
    the expectation is counted from the JSON records, one frame at a time."""
    from types import SimpleNamespace

    from nuparquet.conversion.builder import BuildContext
    from nuparquet.conversion.builders.points import _scene_tasks

    def records(table):
        return json.loads((labelled_root / SYNTH_VERSION / f"{table}.json").read_text())

    modality_of = {s["token"]: s["modality"] for s in records("sensor")}
    sensor_of = {c["token"]: modality_of[c["sensor_token"]] for c in records("calibrated_sensor")}
    scene_of = {s["token"]: s["scene_token"] for s in records("sample")}
    second = records("scene")[1]["token"]
    frames = []
    for frame in records("sample_data"):
        modality, scene = sensor_of[frame["calibrated_sensor_token"]], scene_of[frame["sample_token"]]
        if modality == "lidar" and scene == second:
            continue
        frames.append(frame | {"is_key_frame": frame["is_key_frame"] and not (modality == "radar" and scene == second)})
    tables = {name: pl.DataFrame(records(name)) for name in ("sensor", "calibrated_sensor", "sample", "scene", "log")}
    tables["sample_data"] = pl.DataFrame(frames)
    for modality in ("lidar", "radar"):
        for sweeps in (False, True):
            expected = len({scene_of[f["sample_token"]] for f in frames
                            if sensor_of[f["calibrated_sensor_token"]] == modality and (sweeps or f["is_key_frame"])})
            ctx = BuildContext(labelled_root, SYNTH_VERSION, SimpleNamespace(sweeps=sweeps), None, tables, tmp_path)
            assert _scene_tasks(modality)(ctx) == expected, (modality, sweeps)
    assert [_scene_tasks("radar")(BuildContext(labelled_root, SYNTH_VERSION, SimpleNamespace(sweeps=s), None, tables,
                                               tmp_path)) for s in (False, True)] == [1, 2]  # the cases are reached


def test_a_row_group_holds_whole_frames_up_to_exactly_its_row_limit(tmp_path):
    """`convert_scene` packs whole frames into row groups of at most ROW_GROUP_ROWS points, a new group only when
    the next frame would pass the limit: two frames that fill it exactly share one group, a frame as large as the
    limit has its own, a larger one too. Expected group sizes packed by hand from the frame sizes."""
    from nuparquet.conversion.scene_points import ROW_GROUP_ROWS, SceneTask, convert_scene

    half = ROW_GROUP_ROWS // 2
    sizes = [half, ROW_GROUP_ROWS - half, 100, ROW_GROUP_ROWS, ROW_GROUP_ROWS + 7, 1]
    expected = [ROW_GROUP_ROWS, 100, ROW_GROUP_ROWS, ROW_GROUP_ROWS + 7, 1]
    frames = {key: [] for key in ("token", "channel", "timestamp", "is_key_frame", "filename", "lidarseg", "panoptic")}
    for k, n in enumerate(sizes):
        points = np.zeros((n, 5), np.float32)
        points[:, 0] = np.arange(n)
        (tmp_path / f"frame{k}.pcd.bin").write_bytes(points.tobytes())
        for key, value in (("token", f"frame{k}"), ("channel", "LIDAR_TOP"), ("timestamp", 1000 + k),
                           ("is_key_frame", True), ("filename", f"frame{k}.pcd.bin"), ("lidarseg", None),
                           ("panoptic", None)):
            frames[key].append(value)
    path = tmp_path / "part.parquet"
    summary = convert_scene(SceneTask(str(tmp_path), str(path), 0, "scene-1", "lidar", frames))
    assert summary.written and summary.rows == sum(sizes) and not summary.problems
    metadata = pq.ParquetFile(path).metadata
    assert [metadata.row_group(i).num_rows for i in range(metadata.num_row_groups)] == expected
