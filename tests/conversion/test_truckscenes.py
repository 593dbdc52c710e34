"""`nuparquet convert` of a MAN TruckScenes dataroot against truckscenes-devkit (test-only) on generated data:
detected from its tables, written back byte for byte, the tables equal to the devkit's loaded records, velocities,
boxes of `get_sample_data` / `get_boxes`, the `.pcd` readers, and the inputs it cannot convert exactly refused."""

from __future__ import annotations

import filecmp
import json
import shutil
import types
import warnings

import numpy as np
import polars as pl
import pytest

from nuparquet.conversion import convert
from nuparquet.export.json_files import export_json
from nuparquet.frames.poses import with_sample_poses
from nuparquet.geometry.interpolation import closest_rows
from nuparquet.frames.sensor_boxes import boxes_at
from nuparquet.problems import ProblemsFound
from nuparquet.sources.points import PointFileError, read_radar_pcd
from nuparquet.synth import synthesize

truckscenes = pytest.importorskip("truckscenes")
pypcd4 = pytest.importorskip("pypcd4")
from truckscenes import TruckScenes  # noqa: E402
from truckscenes.utils.data_classes import LidarPointCloud, RadarPointCloud  # noqa: E402
from truckscenes.utils.geometry_utils import BoxVisibility  # noqa: E402

VERSION = "v1.2-mini"
# The devkit's own additions to the records it loads (reverse indexes), not fields of the files.
DECORATIONS = {"sample_annotation": {"category_name"}, "sample_data": {"sensor_modality", "channel"},
               "sample": {"data", "anns"}}


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return synthesize(tmp_path_factory.mktemp("ts") / "root", scenes=2, samples_per_scene=6, seed=3,
                      family="truckscenes", version=VERSION)


@pytest.fixture(scope="module")
def out(root, tmp_path_factory):
    target = tmp_path_factory.mktemp("ts-out") / "out"
    convert(root, VERSION, target, sensors=("lidar", "radar"), sweeps=True)
    return target


@pytest.fixture(scope="module")
def bare(root, tmp_path_factory):
    """A conversion without the points: frames read from their files."""
    target = tmp_path_factory.mktemp("ts-bare") / "out"
    convert(root, VERSION, target)
    return target


@pytest.fixture(scope="module")
def ts(root):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its visualisation dependencies are not installed: no explorer
        return TruckScenes(VERSION, str(root), verbose=False)


def _read(out, name) -> pl.DataFrame:
    return pl.read_parquet(out / name / "*.parquet")


def test_a_truckscenes_dataroot_is_detected_and_every_file_comes_back_byte_for_byte(root, out, tmp_path):
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["source"]["format"] == "truckscenes"
    assert {"frames", "annotations", "scenes", "instances", "sample_ego_motion", "lidar_points",
            "radar_points"} <= set(manifest["datasets"])
    assert manifest["channels"]["camera_layout"] == [["CAMERA_LEFT_FRONT", "CAMERA_RIGHT_FRONT"],
                                                     ["CAMERA_LEFT_BACK", "CAMERA_RIGHT_BACK"]]
    assert len(manifest["channels"]["lidars"]) == 6 and len(manifest["channels"]["radars"]) == 6
    assert manifest["channels"]["reference_lidar"] == "LIDAR_LEFT"  # the devkit's own (eval's add_center_dist)
    export_json(out, tmp_path / "back")
    names = sorted(p.name for p in (root / VERSION).iterdir())
    assert len(names) == 14
    assert manifest["source"]["files"] == {name: {"bytes": (root / VERSION / name).stat().st_size,
                                                  "mtime": (root / VERSION / name).stat().st_mtime} for name in names}
    for name in names:
        assert filecmp.cmp(root / VERSION / name, tmp_path / "back" / VERSION / name, shallow=False), name


def _plain(value):
    return value.tolist() if isinstance(value, np.ndarray) else value


def test_every_table_holds_the_records_the_devkit_loads(out, ts):
    for table in ts.table_names:
        ours = _read(out, f"tables/{table}")
        theirs = getattr(ts, table)
        assert ours["token"].to_list() == [r["token"] for r in theirs], table  # file order: the devkit's list
        for row, record in zip(ours.iter_rows(named=True), theirs):
            for key, value in record.items():
                if key in DECORATIONS.get(table, ()):
                    continue
                got = _plain(row[key])
                if key == "camera_intrinsic":  # flat [9] here, [[3], [3], [3]] (or [] for non-cameras) there
                    got = [] if got is None else [got[0:3], got[3:6], got[6:9]]
                assert got == value and type(got) is type(value), (table, key, record["token"])


def test_velocities_are_the_devkits_box_velocity(out, ts):
    annotations = _read(out, "annotations")
    ours = dict(zip(annotations["token"].to_list(), annotations["velocity"].to_list()))
    expected = np.array([ts.box_velocity(r["token"]) for r in ts.sample_annotation])
    got = np.array([ours[r["token"]] for r in ts.sample_annotation])
    np.testing.assert_array_equal(got, expected)  # the same arithmetic in the same order: exact, NaN where it is
    assert np.isnan(expected[:, 0]).sum() >= 3  # a track of one, and both ends of a gap longer than 1.5 s


def test_scenes_have_no_log_and_keep_their_weather(out, ts):
    scenes = _read(out, "scenes").sort("token")
    assert scenes["log_token"].to_list() == ["", ""]
    for column in ("logfile", "vehicle", "date_captured", "log_location"):
        assert scenes[column].null_count() == 2, column
    assert _read(out, "frames")["log_location"].null_count() == len(ts.sample_data)
    by_token = {r["token"]: r for r in ts.scene}
    for row in scenes.iter_rows(named=True):
        assert row["num_annotations"] == sum(len(s["anns"]) for s in ts.sample if s["scene_token"] == row["token"])
    tables = _read(out, "tables/scene")
    assert (tables["weather_annotation_token"].to_list()
            == [by_token[t]["weather_annotation_token"] for t in tables["token"].to_list()])


def test_closest_pose_is_the_devkits_getclosest_with_its_ties():
    # poses out of order, two sharing a timestamp (the later written wins), and queries on, between (a tie goes
    # to the earlier) and beyond the ends
    stamps = np.array([30, 10, 20, 20, 50, 40], dtype=np.int64)
    tokens = [f"p{i}" for i in range(len(stamps))]
    pairs = sorted(zip(stamps.tolist(), tokens), key=lambda e: e[0])
    fake = types.SimpleNamespace(_timestamp2token={"ego_pose": dict(pairs)},
                                 get=lambda table, token: {"token": token})
    queries = np.array([0, 10, 14, 15, 16, 20, 25, 26, 45, 50, 99], dtype=np.int64)
    expected = [TruckScenes.getclosest(fake, "ego_pose", int(t))["token"] for t in queries]
    assert [tokens[i] for i in closest_rows(stamps, queries)] == expected
    assert expected[5] == "p3" and expected[3] == "p1"


def _frames_for_boxes(out):
    frames = _read(out, "frames").filter(pl.col("modality").cast(pl.String) != "radar")
    poses, samples = _read(out, "tables/ego_pose"), _read(out, "tables/sample")
    return frames, with_sample_poses(frames, poses, samples)


def test_boxes_in_the_sensor_frame_are_the_devkits_get_sample_data(out, ts):
    frames, moved = _frames_for_boxes(out)
    ours = boxes_at(moved, _read(out, "annotations"), _read(out, "tables/sample"), visibility="any", at="sensor")
    tokens = frames["token"].to_list()
    seen = 0
    for i, token in enumerate(tokens):
        _path, boxes, intrinsic = ts.get_sample_data(token, box_vis_level=BoxVisibility.ANY)
        boxes = sorted(boxes, key=lambda b: b.token)
        mine = ours.filter(pl.col("frame_index") == i).sort("annotation_token")
        assert mine["annotation_token"].to_list() == [b.token for b in boxes], token
        if boxes:
            np.testing.assert_allclose(np.stack(mine["translation"].to_numpy()), [b.center for b in boxes],
                                       rtol=0, atol=1e-9)
            np.testing.assert_allclose(np.stack(mine["rotation"].to_numpy()),
                                       [b.orientation.elements for b in boxes], rtol=0, atol=1e-12)
            np.testing.assert_array_equal(np.stack(mine["size"].to_numpy()), [b.wlh for b in boxes])
        row = frames.row(i, named=True)
        if intrinsic is None:
            assert row["camera_intrinsic"] is None
        else:
            np.testing.assert_array_equal(np.reshape(row["camera_intrinsic"], (3, 3)), intrinsic)
        seen += len(boxes)
    assert seen > 100
    # the frame's own pose is not the one the devkit moves boxes with: using it would move them elsewhere
    own = boxes_at(frames, _read(out, "annotations"), _read(out, "tables/sample"), visibility="none", at="sensor")
    again = boxes_at(moved, _read(out, "annotations"), _read(out, "tables/sample"), visibility="none", at="sensor")
    assert np.abs(np.stack(own["translation"].to_numpy()) - np.stack(again["translation"].to_numpy())).max() > 0.01


def test_boxes_of_sweeps_are_the_devkits_get_boxes(out, ts):
    frames = _read(out, "frames").filter(~pl.col("is_key_frame"))
    ours = boxes_at(frames, _read(out, "annotations"), _read(out, "tables/sample"), visibility="none", at="global")
    assert ours["interpolated"].any()
    for i, token in enumerate(frames["token"].to_list()):
        boxes = sorted(ts.get_boxes(token), key=lambda b: b.token)
        mine = ours.filter(pl.col("frame_index") == i).sort("annotation_token")
        assert mine["annotation_token"].to_list() == [b.token for b in boxes]
        np.testing.assert_allclose(np.stack(mine["translation"].to_numpy()), [b.center for b in boxes], rtol=0,
                                   atol=1e-9)
        np.testing.assert_allclose(np.stack(mine["rotation"].to_numpy()), [b.orientation.elements for b in boxes],
                                   rtol=0, atol=1e-12)


def test_pcd_files_read_as_the_devkit_reads_them(root, out, ts):
    lidar = [r for r in ts.sample_data if r["sensor_modality"] == "lidar"][:12]
    for record in lidar:
        path = root / record["filename"]
        points = read_radar_pcd(path)
        reference = pypcd4.PointCloud.from_path(path).pc_data
        assert points.dtype.names == reference.dtype.names
        for name in points.dtype.names:
            np.testing.assert_array_equal(points[name], reference[name])
        cloud = LidarPointCloud.from_file(str(path))
        np.testing.assert_array_equal(np.array([points[n] for n in ("x", "y", "z", "intensity")], np.float64),
                                      cloud.points)
        np.testing.assert_array_equal(points["timestamp"], cloud.timestamps[0])
    converted = _read(out, "lidar_points")
    assert converted["ring"].null_count() == converted.height
    for record in lidar:
        mine = converted.filter(pl.col("sample_data_token") == record["token"]).sort("point_index")
        cloud = LidarPointCloud.from_file(str(root / record["filename"]))
        np.testing.assert_array_equal(mine.select("x", "y", "z", "intensity").to_numpy().astype(np.float64).T,
                                      cloud.points)
        assert mine["point_timestamp"].dtype == pl.UInt64
        np.testing.assert_array_equal(mine["point_timestamp"].to_numpy(), cloud.timestamps[0])
    radar = _read(out, "radar_points")
    fields = ["x", "y", "z", "vrel_x", "vrel_y", "vrel_z", "rcs"]
    frames = [r for r in ts.sample_data if r["sensor_modality"] == "radar"]
    assert radar["sample_data_token"].n_unique() == len(frames)  # keyframes and sweeps
    for record in frames[:12]:
        mine = radar.filter(pl.col("sample_data_token") == record["token"]).sort("point_index")
        cloud = RadarPointCloud.from_file(str(root / record["filename"]))
        np.testing.assert_array_equal(mine.select(fields).to_numpy().astype(np.float64).T, cloud.points)


def _copy(root, tmp_path):
    target = tmp_path / "copy"
    shutil.copytree(root / VERSION, target / VERSION)
    return target


def _edit(root, table, change):
    path = root / VERSION / f"{table}.json"
    records = json.loads(path.read_text())
    change(records)
    path.write_text(json.dumps(records, indent=2))


def test_an_ego_motion_field_of_another_type_is_refused_by_file_and_field(root, tmp_path):
    copy = _copy(root, tmp_path)
    _edit(copy, "ego_motion_chassis", lambda records: records[3].update(vx="12.0"))
    with pytest.raises(ProblemsFound) as caught:
        convert(copy, VERSION, tmp_path / "out")
    text = str(caught.value)
    assert "ego_motion_chassis.json" in text and "'vx'" in text


def test_a_missing_ego_motion_field_is_refused(root, tmp_path):
    copy = _copy(root, tmp_path)
    _edit(copy, "ego_motion_cabin", lambda records: [r.pop("roll_rate") for r in records])
    with pytest.raises(ProblemsFound, match=r"ego_motion_cabin.json.*'roll_rate' is missing"):
        convert(copy, VERSION, tmp_path / "out")


def test_a_weather_token_that_names_no_record_is_refused(root, tmp_path):
    copy = _copy(root, tmp_path)
    _edit(copy, "scene", lambda records: records[1].update(weather_annotation_token="nowhere"))
    token = json.loads((copy / VERSION / "scene.json").read_text())[1]["token"]
    with pytest.raises(ProblemsFound, match=rf"scene.json\[1\] token={token}: .*weather_annotation_token 'nowhere' "
                                            "does not resolve"):
        convert(copy, VERSION, tmp_path / "out")


def test_a_weather_record_without_a_string_token_is_refused(root, tmp_path):
    copy = _copy(root, tmp_path)
    _edit(copy, "weather_annotation", lambda records: [r.update(token=i) for i, r in enumerate(records)])
    with pytest.raises(ProblemsFound, match=r"weather_annotation.json.*field 'token' must be a string"):
        convert(copy, VERSION, tmp_path / "out")


def test_allow_dangling_leaves_the_references_unchecked_as_for_nuscenes(root, tmp_path):
    from nuparquet.conversion import validate

    copy = _copy(root, tmp_path)
    _edit(copy, "sample_annotation", lambda records: records[0].update(instance_token="gone"))
    strict = validate(copy, VERSION)
    assert sorted(p.file for p in strict.problems) == ["instance.json", "sample_annotation.json"]  # and its count
    assert "instance_token 'gone'" in " ".join(str(p) for p in strict.problems)
    assert validate(copy, VERSION, allow_dangling=True).problems == []


def test_without_weather_annotation_it_converts_as_the_devkit_loads_it(root, tmp_path):
    copy = _copy(root, tmp_path)
    (copy / VERSION / "weather_annotation.json").unlink()
    _edit(copy, "scene", lambda records: [r.pop("weather_annotation_token") for r in records])
    convert(copy, VERSION, tmp_path / "out")
    export_json(tmp_path / "out", tmp_path / "back")
    assert sorted(p.name for p in (tmp_path / "back" / VERSION).iterdir()) == sorted(
        p.name for p in (copy / VERSION).iterdir())
    assert filecmp.cmp(copy / VERSION / "scene.json", tmp_path / "back" / VERSION / "scene.json", shallow=False)


def test_a_compressed_pcd_is_refused_naming_the_file(root, tmp_path):
    copy = _copy(root, tmp_path)
    record = next(r for r in json.loads((root / VERSION / "sample_data.json").read_text())
                  if r["filename"].startswith("samples/RADAR_LEFT_FRONT"))
    for folder in ("samples", "sweeps"):
        shutil.copytree(root / folder, copy / folder)
    path = copy / record["filename"]  # pypcd4 can write LZF-compressed files; this reader takes binary only
    path.write_bytes(path.read_bytes().replace(b"DATA binary\n", b"DATA binary_compressed\n", 1))
    with pytest.raises(PointFileError, match="binary_compressed"):
        read_radar_pcd(copy / record["filename"])
    with pytest.raises(ProblemsFound, match=record["filename"]):
        convert(copy, VERSION, tmp_path / "out", sensors=("radar",))


def test_a_lidar_pcd_without_intensity_or_of_another_type_is_refused_naming_the_file(root, tmp_path):
    copy = _copy(root, tmp_path)
    for folder in ("samples", "sweeps"):
        shutil.copytree(root / folder, copy / folder)
    records = json.loads((root / VERSION / "sample_data.json").read_text())
    first, second = [r["filename"] for r in records if r["filename"].startswith("samples/LIDAR_REAR")][:2]
    cloud = pypcd4.PointCloud.from_path(root / first)
    data = cloud.pc_data
    pypcd4.PointCloud.from_points([data["x"], data["y"], data["z"], data["timestamp"]],
                                  ("x", "y", "z", "timestamp"), (np.float32,) * 3 + (np.uint64,)).save(copy / first)
    pypcd4.PointCloud.from_points([data[n] for n in ("x", "y", "z", "intensity", "timestamp")],
                                  ("x", "y", "z", "intensity", "timestamp"),
                                  (np.float32,) * 3 + (np.float64, np.uint64)).save(copy / second)
    with pytest.raises(ProblemsFound) as caught:
        convert(copy, VERSION, tmp_path / "out", sensors=("lidar",))
    text = str(caught.value)
    assert f"{first}" in text and "no field 'intensity'" in text
    assert f"{second}" in text and "'intensity' is float64" in text


def test_the_generator_lays_out_keyframes_and_sweeps_as_nuscenes(ts, root):
    for scene in ts.scene:  # a scene names its first and its last sample, the ends of its chain
        first, last = ts.get("sample", scene["first_sample_token"]), ts.get("sample", scene["last_sample_token"])
        assert first["prev"] == "" and last["next"] == "" and first["scene_token"] == scene["token"]
    for record in ts.sample_data:
        folder = "samples" if record["is_key_frame"] else "sweeps"
        assert record["filename"] == f"{folder}/{record['channel']}/{record['channel']}_{record['timestamp']}." + (
            "jpg" if record["sensor_modality"] == "camera" else "pcd")
        assert (root / record["filename"]).is_file()


def test_the_generator_is_deterministic(root, tmp_path):
    again = synthesize(tmp_path / "again", scenes=2, samples_per_scene=6, seed=3, family="truckscenes",
                       version=VERSION)
    for path in sorted((root / VERSION).iterdir()):
        assert filecmp.cmp(path, again / VERSION / path.name, shallow=False), path.name


@pytest.mark.parametrize("points", ["converted", "files"])
def test_a_lidar_pcd_read_through_the_dataset_is_the_devkits_cloud(root, out, bare, ts, points):
    import nuparquet

    ds = nuparquet.open(out if points == "converted" else bare, dataroot=root)
    frames = [r for r in ts.sample_data if r["sensor_modality"] == "lidar"]
    for record in frames[::7]:
        points, _ = ds.sensors.lidar(record["token"], record["filename"])
        cloud = LidarPointCloud.from_file(str(root / record["filename"]))
        np.testing.assert_array_equal(points.astype(np.float64).T, cloud.points)
        every = ds.sensors.points(record["token"], record["filename"], "lidar", columns=["x", "point_timestamp"])
        assert every.columns == ["x", "point_timestamp"]
        np.testing.assert_array_equal(every["point_timestamp"].to_numpy(), cloud.timestamps[0])


def test_ego_motion_is_aligned_to_every_sample(out, ts):
    rows = _read(out, "sample_ego_motion")
    assert rows.height == len(ts.sample)
    for table in ("ego_motion_cabin", "ego_motion_chassis"):
        records = sorted(getattr(ts, table), key=lambda r: r["timestamp"])
        stamps = np.array([r["timestamp"] for r in records])
        floats = [k for k, v in records[0].items() if isinstance(v, float)]
        interpolated = 0
        for row in rows.iter_rows(named=True):
            t = row["timestamp"]
            assert row[f"{table}_closest_token"] == ts.getclosest(table, t)["token"]
            before = int(np.searchsorted(stamps, t, side="right")) - 1
            assert row[table] == records[before] and row[f"{table}_age_us"] == t - stamps[before]
            if stamps[before] < t < stamps[-1]:
                a, b = records[before], records[before + 1]
                for name in floats:
                    expected = np.interp(t, [a["timestamp"], b["timestamp"]], [a[name], b[name]])
                    assert row[f"{table}_interp"][name] == pytest.approx(expected, rel=1e-12, abs=1e-15), name
                interpolated += 1
        assert interpolated == len(ts.sample)


@pytest.mark.parametrize("points", ["converted", "files"])
@pytest.mark.parametrize("channel, kind", [("LIDAR_TOP_LEFT", LidarPointCloud), ("RADAR_RIGHT_SIDE", RadarPointCloud)])
def test_multisweep_is_the_devkits_from_file_multisweep(root, out, bare, ts, channel, kind, points):
    import nuparquet
    from nuparquet.frames.sweeps import multisweep

    ds = nuparquet.open(out if points == "converted" else bare, dataroot=root)
    for sample in ts.sample[4:7]:  # the last sample of a scene, and the first (no sweep before it) of the next
        cloud, times = kind.from_file_multisweep(ts, sample, channel, "LIDAR_LEFT", nsweeps=3)
        sweeps = multisweep(ds, sample["token"], channel, "LIDAR_LEFT", nsweeps=3)
        assert sweeps.points.dtype == np.float64 and sweeps.points.shape == cloud.points.T.shape
        np.testing.assert_allclose(sweeps.points, cloud.points.T, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(sweeps.times_s, times[0])


def test_its_schemas_are_nuscenes_less_log_and_map_plus_its_own_and_every_reference_names_one():
    from nuparquet.sources.truckscenes import schemas

    found = schemas()
    assert set(found) == {"attribute", "calibrated_sensor", "category", "ego_motion_cabin", "ego_motion_chassis",
                          "ego_pose", "instance", "sample", "sample_annotation", "sample_data", "scene", "sensor",
                          "visibility"}
    assert "log" not in {f.ref for f in found["scene"].fields}
    for schema in found.values():
        for field in schema.fields:
            assert field.ref is None or field.ref in found, f"{schema.name}.{field.name}"


def test_an_empty_ego_motion_table_converts_with_null_alignments(root, tmp_path):
    """A recording whose cabin motion was not logged (`ego_motion_cabin.json` is `[]`) still converts: every sample's
    cabin record, age, interpolation and closest token are null (there is none), the chassis ones are filled, and the
    empty table comes back byte for byte."""
    copy = _copy(root, tmp_path)
    _edit(copy, "ego_motion_cabin", lambda records: records.clear())
    convert(copy, VERSION, tmp_path / "out")
    rows = _read(tmp_path / "out", "sample_ego_motion")
    assert rows.height > 0 and rows.schema["ego_motion_cabin_closest_token"] == pl.String
    for column in ("ego_motion_cabin", "ego_motion_cabin_age_us", "ego_motion_cabin_closest_token"):
        assert rows[column].null_count() == rows.height, column
    assert rows["ego_motion_chassis_closest_token"].null_count() == 0
    export_json(tmp_path / "out", tmp_path / "back")
    assert json.loads((tmp_path / "back" / VERSION / "ego_motion_cabin.json").read_text()) == []


def test_the_sensor_reader_reads_a_pcd_lidar_file_as_lidar_points_names_its_fields(root, bare, ts):
    """An output converted without its points reads each lidar `.pcd` through the one sensor reader: x, y, z,
    intensity as the devkit's `LidarPointCloud.from_file` and `point_timestamp` as its timestamps."""
    import nuparquet

    ds = nuparquet.open(bare, dataroot=root)
    assert not ds.sensors.converted_columns("lidar")
    for record in [r for r in ts.sample_data if r["sensor_modality"] == "lidar"][:6]:
        frame = ds.sensors.points(record["token"], record["filename"], "lidar",
                                  ["x", "y", "z", "intensity", "point_timestamp"])
        cloud = LidarPointCloud.from_file(str(root / record["filename"]))
        assert frame.columns == ["x", "y", "z", "intensity", "point_timestamp"]
        np.testing.assert_array_equal(frame.select("x", "y", "z", "intensity").to_numpy().astype(np.float64).T,
                                      cloud.points)
        np.testing.assert_array_equal(frame["point_timestamp"].to_numpy(), cloud.timestamps[0])
