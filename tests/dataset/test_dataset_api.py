"""The face of one converted output (`nuparquet.open` -> `Dataset`) and how every verb takes its options: names
`scan` accepts, wrong arguments that are errors (never silent empties), and options as objects or fields."""

from __future__ import annotations

import dataclasses
import json

import polars as pl
import pytest

import nuparquet
from conftest import SYNTH_VERSION
from nuparquet.errors import UsageError


@pytest.fixture(scope="module")
def points_out(labelled_root, tmp_path_factory):
    """The labelled synthetic set (2 scenes x 3 samples) converted with its lidar and radar points."""
    out = tmp_path_factory.mktemp("api-points") / "out"
    nuparquet.convert(labelled_root, SYNTH_VERSION, out, sensors=("lidar", "radar"), workers=1)
    return out


def test_scan_takes_every_name_sql_takes(synth_out):
    ds = nuparquet.open(synth_out)
    table = ds.scan("tables/sample").collect()
    assert table.height > 0
    for alias in ("sample", "tables_sample"):
        assert ds.scan(alias).collect().equals(table)
        assert ds.sql(f"SELECT COUNT(*) AS n FROM {alias}")["n"].item() == table.height
    assert ds.scan("map/lane").collect().height == ds.sql('SELECT COUNT(*) AS n FROM "map/lane"')["n"].item()
    with pytest.raises(UsageError, match="no dataset 'samples'.*valid names: frames"):
        ds.scan("samples")


def test_unknown_scenes_are_named_with_close_matches_and_the_valid_ones(synth_out):
    ds = nuparquet.open(synth_out)
    names = ds.scene_names()
    assert names == sorted(names) and len(names) == 2
    ds.check_scenes(names)  # every known name passes
    with pytest.raises(UsageError) as error:
        ds.check_scenes([names[0], names[0][:-1] + "9", "nowhere"])
    message = str(error.value)
    assert message.startswith(f"unknown scenes '{names[0][:-1]}9', 'nowhere' (did you mean ")
    assert f"valid scenes: {', '.join(names)}" in message
    ds._scene_names = [f"scene-{i:04d}" for i in range(25)]  # a long listing is cut at 20 and counted
    with pytest.raises(UsageError, match=r"valid scenes: scene-0000, .*scene-0019 \.\.\. \(25 in all\)$"):
        ds.check_scenes(["x"])


def test_points_of_an_unknown_scene_or_channel_are_errors_not_empty_results(points_out):
    ds = nuparquet.open(points_out)
    scene = ds.scene_names()[0]
    assert len(ds.points(scene=scene)) > 0 and len(ds.radar_points(scene=scene)) > 0
    with pytest.raises(UsageError, match="unknown scene 'scene-9999'"):
        ds.points(scene="scene-9999")
    with pytest.raises(UsageError, match="unknown lidar channel 'CAM_FRONT'; valid: LIDAR_TOP"):
        ds.points(scene=scene, channel="CAM_FRONT")
    with pytest.raises(UsageError, match="unknown radar channel 'LIDAR_TOP'; valid: RADAR_BACK_LEFT"):
        ds.radar_points(scene=scene, channel="LIDAR_TOP")
    # a channel of the right kind that this scene happens to lack would be empty, not an error: both radars exist
    assert len(ds.radar_points(scene=scene, channel="RADAR_FRONT")) > 0


def test_inventory_counts_rows_files_and_bytes_of_every_dataset_on_disk(synth_out):
    import json

    import pyarrow.parquet as pq

    manifest = json.loads((synth_out / "manifest.json").read_text())
    expected = []
    for name, entry in manifest["datasets"].items():
        paths = sorted((synth_out / entry["path"]).rglob("*.parquet"))
        expected.append((name, sum(pq.read_metadata(p).num_rows for p in paths), entry["rows"], len(paths),
                         sum(p.stat().st_size for p in paths)))
    inventory = nuparquet.open(synth_out).inventory()
    assert inventory.columns == ["dataset", "rows", "manifest_rows", "files", "bytes"]
    assert inventory.rows() == expected
    assert len(expected) > 4 and all(files > 0 and rows == manifest_rows for _, rows, manifest_rows, files, _ in expected)


def test_a_many_scene_job_writes_into_a_directory_never_over_a_file(tmp_path):
    from nuparquet.dataset.selection import check_out_dir

    assert check_out_dir(tmp_path) == tmp_path  # an existing directory
    assert check_out_dir(str(tmp_path / "new")) == tmp_path / "new"  # one to be made
    (tmp_path / "taken").write_text("x")
    with pytest.raises(UsageError, match=f"--out-dir {tmp_path / 'taken'} is a file; give a directory"):
        check_out_dir(tmp_path / "taken")
    with pytest.raises(UsageError, match="give --out-dir DIR"):
        check_out_dir(None)


@pytest.fixture(scope="module")
def radar_states_out(labelled_root, tmp_path_factory):
    """(the labelled synthetic set with its radar keyframes' states varied, that set converted with its radar
    points): of every four points one is invalid, one has dyn_prop 7, one is ambiguous (ambig_state 4), one passes
    the devkit's default filters (the generator writes only points that pass)."""
    import os
    import shutil

    import numpy as np

    from nuparquet.synth.sensors import _RADAR_DTYPE

    base = tmp_path_factory.mktemp("radar-states")
    root = base / "data"
    shutil.copytree(labelled_root, root, copy_function=os.symlink)  # links, but for the radar files rewritten below
    for path in root.glob("samples/RADAR_*/*.pcd"):
        data = path.read_bytes()
        start = data.index(b"DATA binary\n") + len(b"DATA binary\n")
        count = (len(data) - start) // _RADAR_DTYPE.itemsize
        points = np.frombuffer(data, _RADAR_DTYPE, count, start).copy()
        points["invalid_state"][1::4], points["dyn_prop"][2::4], points["ambig_state"][3::4] = 1, 7, 4
        path.unlink()
        path.write_bytes(data[:start] + points.tobytes() + data[start + points.nbytes:])
    nuparquet.convert(root, SYNTH_VERSION, base / "out", sensors=("radar",), workers=1)
    return root, base / "out"


def test_filtered_radar_points_are_those_the_devkits_default_filters_keep(radar_states_out):
    import numpy as np
    from nuscenes.utils.data_classes import RadarPointCloud

    root, out = radar_states_out
    ds = nuparquet.open(out)
    scene = ds.scene_names()[0]
    frames = (ds.scan("frames").filter((pl.col("scene_name") == scene) & pl.col("is_key_frame")
                                       & pl.col("channel").cast(pl.String).str.starts_with("RADAR"))
              .select("token", "filename").collect())
    kept = total = 0
    for token, filename in frames.iter_rows():
        expected = RadarPointCloud.from_file(str(root / filename)).points.T  # the default filters
        filtered = ds.radar_points(token, filtered=True)
        np.testing.assert_array_equal(filtered, expected)
        kept, total = kept + len(filtered), total + len(ds.radar_points(token))
    assert len(frames) > 0 and 0 < kept < total  # some points removed, not all
    with_flag = ds.radar_points(scene=scene, columns=["x", "passes_default_filters"], filtered=True)
    assert with_flag.height == kept and with_flag["passes_default_filters"].all()
    assert ds.radar_points(scene=scene, columns=["x"], filtered=True).columns == ["x"]


def test_frames_given_by_token_must_exist_and_keep_their_order(synth_out):
    ds = nuparquet.open(synth_out)
    tokens = ds.scan("frames").select("token").head(3).collect()["token"].to_list()[::-1]
    assert ds.frame_rows(tokens).collect()["token"].to_list() == tokens
    assert ds.frame_rows(tokens[1]).collect()["token"].to_list() == [tokens[1]]  # one token, not its characters
    with pytest.raises(UsageError, match="no frame \\(sample_data\\) 'nope'"):
        ds.boxes([tokens[0], "nope"])
    missing = [f"missing-{i}" for i in range(6)]  # six missing: the first five named, then "..."
    with pytest.raises(UsageError, match=r"^no frame \(sample_data\) 'missing-0', 'missing-1', 'missing-2', "
                                         r"'missing-3', 'missing-4' \.\.\. in "):
        ds.frame_rows([tokens[0], *missing])
    with pytest.raises(ValueError, match="visibility must be one of any, all, none"):
        ds.boxes(tokens, visibility="some")
    with pytest.raises(ValueError, match="at must be one of global, ego, sensor"):
        ds.boxes(tokens, at="camera")


def test_annotations_in_file_order_are_the_annotations_in_sample_annotation_json_record_order(synth_root, synth_out):
    """The devkit lists a sample's boxes in sample_annotation.json's record order; the annotations dataset itself is
    sorted by scene and time, so the order comes from the source table."""
    records = json.loads((synth_root / SYNTH_VERSION / "sample_annotation.json").read_text())
    ds = nuparquet.open(synth_out)
    ours = ds.annotations_in_file_order().collect()
    assert ours["token"].to_list() == [r["token"] for r in records]
    assert ours["token"].to_list() != ds.scan("annotations").select("token").collect()["token"].to_list()
    assert ours.columns == ds.scan("annotations").collect_schema().names()  # the annotations' own columns


def test_the_map_of_a_location_is_read_once_and_refuses_unknown_lanes(synth_out):
    ds = nuparquet.open(synth_out)
    location = ds.scan("map/lane").select("location").unique().collect()["location"][0]
    layers = ds.map(location)
    assert ds.map(location) is layers
    lane = ds.scan("map/lane").filter(pl.col("location") == location).select("token").head(1).collect().item()
    assert len(layers.discretize_lanes([lane], 0.5)[lane]) > 1
    with pytest.raises(UsageError, match=f"no lane or lane connector 'unknown' in the map of {location}"):
        layers.discretize_lanes([lane, "unknown"], 0.5)


def test_options_are_an_object_keyword_fields_or_both_and_a_typo_is_an_error():
    from nuparquet.options import resolve, split_fields

    base = nuparquet.RenderOptions(channel="all", scale=0.3)
    assert resolve(nuparquet.RenderOptions, None, {"scale": 0.3}) == nuparquet.RenderOptions(scale=0.3)
    assert resolve(nuparquet.RenderOptions, base, {}) is base
    # a keyword sets a field the object leaves at its default, or repeats a value it holds ...
    assert resolve(nuparquet.RenderOptions, base, {"fps": 5.0, "channel": "all"}) == dataclasses.replace(base, fps=5.0)
    # ... and one that says otherwise than the object is an error naming the field, whichever way it goes
    with pytest.raises(TypeError, match="option\\(s\\) scale given both in the RenderOptions object and as keywords"):
        resolve(nuparquet.RenderOptions, base, {"scale": 1.0})
    with pytest.raises(TypeError, match="option\\(s\\) channel, scale given both"):
        resolve(nuparquet.RenderOptions, base, {"scale": 0.5, "channel": None})  # back to the defaults, also a conflict
    with pytest.raises(TypeError, match="unknown option\\(s\\) scael for RenderOptions; valid: all_frames"):
        resolve(nuparquet.RenderOptions, None, {"scael": 1.0})
    with pytest.raises(TypeError, match="expected RenderOptions, got ConvertOptions"):
        resolve(nuparquet.RenderOptions, nuparquet.ConvertOptions(), {})
    convert_fields, engine_fields = split_fields({"sensors": ("lidar",), "workers": 2},
                                                 nuparquet.ConvertOptions, nuparquet.EngineOptions)
    assert convert_fields == {"sensors": ("lidar",)} and engine_fields == {"workers": 2}
    with pytest.raises(TypeError, match="unknown option 'jobs'"):
        split_fields({"jobs": 2}, nuparquet.ConvertOptions, nuparquet.EngineOptions)


def test_values_are_checked_once_when_the_options_are_built():
    with pytest.raises(UsageError, match="--scale must be in \\(0, 4\\]"):
        nuparquet.RenderOptions(scale=0)
    with pytest.raises(UsageError, match="--workers must be 0 \\(every core\\) or more"):
        nuparquet.EngineOptions(workers=-1)
    assert nuparquet.EngineOptions(workers=0).workers is None  # 0: every core, as --jobs 0 always meant
    with pytest.raises(UsageError, match="--sensors takes lidar, radar"):
        nuparquet.ConvertOptions(sensors="lidar,camera")
    with pytest.raises(UsageError, match="--max-sweeps must be >= 0"):
        nuparquet.IndexOptions(max_sweeps=-1)
    assert nuparquet.IndexOptions(cameras="CAM_BACK, CAM_FRONT").cameras == ("CAM_BACK", "CAM_FRONT")
    with pytest.raises(UsageError, match="--scenes must be a positive integer"):
        nuparquet.SynthOptions(scenes=0)


def test_convert_takes_an_options_object_or_fields_alike(labelled_root, tmp_path):
    by_object = nuparquet.convert(labelled_root, SYNTH_VERSION, tmp_path / "a",
                                  nuparquet.ConvertOptions(scenes_per_batch=1, no_map=True))
    by_fields = nuparquet.convert(labelled_root, SYNTH_VERSION, tmp_path / "b", scenes_per_batch=1, no_map=True)
    assert by_object["options"] == by_fields["options"]
    assert by_object["options"]["scenes_per_batch"] == 1 and by_object["options"]["no_map"] is True
    assert {k: v["rows"] for k, v in by_object["datasets"].items()} == {k: v["rows"] for k, v in by_fields["datasets"].items()}
    assert not any(name.startswith("map/") for name in by_object["datasets"])


def test_the_jobs_flag_is_kept_as_the_spelling_of_workers(labelled_root, tmp_path):
    from nuparquet.cli.main import main

    assert main(["convert", str(labelled_root), "--version", SYNTH_VERSION, "--out", str(tmp_path / "o"),
                 "--sensors", "lidar", "--jobs", "1", "--quiet"]) == 0
    assert nuparquet.open(tmp_path / "o").manifest["options"]["jobs"] == 1


def test_points_are_read_safely_from_several_threads_at_once(points_out):
    """The renderer reads lidar points from its decode threads: one Dataset's points read concurrently equal the
    points read one at a time (a shared pyarrow ParquetFile read from two threads raised or crashed)."""
    from concurrent.futures import ThreadPoolExecutor

    import numpy as np

    ds = nuparquet.open(points_out)
    tokens = (ds.scan("lidar_points").select("sample_data_token").unique(maintain_order=True).collect()
              ["sample_data_token"].to_list())
    expected = {token: np.array(ds.points(token)) for token in tokens}
    fresh = nuparquet.open(points_out)  # its row-group index and open files are shared by the threads below
    with ThreadPoolExecutor(max_workers=4) as pool:
        for _ in range(5):
            for token, points in zip(tokens, pool.map(fresh.points, tokens)):
                np.testing.assert_array_equal(points, expected[token])


def test_as_dataset_opens_a_path_and_hands_a_dataset_back_as_it_is(synth_out):
    """What every verb accepts: a path (Path or str) is opened as `nuparquet.open` opens it; a Dataset is used
    as given (its caches kept), never reopened."""
    import json

    from nuparquet.dataset import Dataset, as_dataset

    manifest = json.loads((synth_out / "manifest.json").read_text())
    for given in (synth_out, str(synth_out)):
        ds = as_dataset(given)
        assert isinstance(ds, Dataset) and ds.root == str(synth_out.resolve()) and ds.manifest == manifest
    opened = nuparquet.open(synth_out)
    assert as_dataset(opened) is opened


def test_where_picks_the_scenes_whose_row_passes_the_condition_sorted(synth_root, synth_out):
    """`select_scenes` with an SQL condition on the scenes dataset, against the scenes of scene.json: the names
    whose row passes, sorted; with names as well, the names that also pass."""
    import json

    from nuparquet.dataset import select_scenes

    scenes = json.loads((synth_root / SYNTH_VERSION / "scene.json").read_text())
    names = sorted(s["name"] for s in scenes)
    ds = nuparquet.open(synth_out)
    assert select_scenes(ds, where=f"name <> '{names[0]}'") == names[1:]
    assert select_scenes(ds, where=f"nbr_samples = {scenes[0]['nbr_samples']}") == sorted(
        s["name"] for s in scenes if s["nbr_samples"] == scenes[0]["nbr_samples"])
    assert select_scenes(ds, scenes=tuple(names), where=f"name = '{names[-1]}'") == [names[-1]]
    with pytest.raises(UsageError, match="no scene selected by --where \"name = 'nowhere'\""):
        select_scenes(ds, where="name = 'nowhere'")


def test_the_radar_points_of_one_channel_are_that_channels_keyframes_as_the_devkit_reads_them(radar_states_out):
    """`radar_points(scene=..., channel=...)`: the points of that radar's keyframes of the scene only, in time
    order, each frame as devkit `RadarPointCloud.from_file` reads its file (filtered: the devkit's defaults)."""
    import numpy as np
    from nuscenes.utils.data_classes import RadarPointCloud

    root, out = radar_states_out
    ds = nuparquet.open(out)
    scene = ds.scene_names()[0]
    frames = (ds.scan("frames").filter((pl.col("scene_name") == scene) & pl.col("is_key_frame")
                                       & pl.col("channel").cast(pl.String).str.starts_with("RADAR"))
              .select(pl.col("channel").cast(pl.String), "timestamp", "filename").sort("timestamp").collect())
    channels = sorted(set(frames["channel"]))
    assert len(channels) > 1  # another radar's points would be seen
    for channel in channels:
        files = frames.filter(pl.col("channel") == channel)["filename"].to_list()
        expected = np.concatenate([RadarPointCloud.from_file(str(root / f)).points.T for f in files])
        np.testing.assert_array_equal(ds.radar_points(scene=scene, channel=channel, filtered=True), expected)


@pytest.fixture(scope="module")
def short_radar_out(labelled_root, tmp_path_factory):
    """The labelled synthetic set with every radar file cut to its first six fields (x y z dyn_prop id rcs: fewer
    than the devkit's 18, so no default-filter flag), converted with its radar points."""
    import os
    import shutil

    import numpy as np

    from nuparquet.synth.sensors import _RADAR_DTYPE

    base = tmp_path_factory.mktemp("short-radar")
    root = base / "data"
    shutil.copytree(labelled_root, root, copy_function=os.symlink)  # links, but for the radar files rewritten below
    kept = list(_RADAR_DTYPE.names[:6])
    for path in root.glob("samples/RADAR_*/*.pcd"):
        data = path.read_bytes()
        start = data.index(b"DATA binary\n") + len(b"DATA binary\n")
        points = np.frombuffer(data, _RADAR_DTYPE, (len(data) - start) // _RADAR_DTYPE.itemsize, start)
        short = np.empty(len(points), [(n, _RADAR_DTYPE[n]) for n in kept])
        for name in kept:
            short[name] = points[name]
        header = ["# .PCD v0.7 - Point Cloud Data file format", "VERSION 0.7", f"FIELDS {' '.join(kept)}",
                  "SIZE " + " ".join(str(_RADAR_DTYPE[n].itemsize) for n in kept),
                  "TYPE " + " ".join("F" if _RADAR_DTYPE[n].kind == "f" else "I" if _RADAR_DTYPE[n].kind == "i"
                                     else "U" for n in kept),
                  "COUNT " + " ".join("1" for _ in kept), f"WIDTH {len(points)}", "HEIGHT 1",
                  "VIEWPOINT 0 0 0 1 0 0 0", f"POINTS {len(points)}", "DATA binary"]
        path.unlink()
        path.write_bytes(("\n".join(header) + "\n").encode("ascii") + short.tobytes())
    nuparquet.convert(root, SYNTH_VERSION, base / "out", sensors=("radar",), workers=1)
    return base / "out"


def test_filtered_radar_points_of_files_without_the_devkits_fields_are_every_point_as_read_from_the_files(
        short_radar_out):
    """A PCD of fewer than the devkit's 18 fields has no default-filter flag (null: the devkit's filters, by field
    position, do not apply): `filtered=True` keeps every point, as the renderers' own reading of such a file does
    (`frame_cloud` without radar_points, `sources.points.passes_default_filters` None), not none of them."""
    import numpy as np

    from nuparquet.sources.points import passes_default_filters, read_radar_pcd

    ds = nuparquet.open(short_radar_out)
    scene = ds.scene_names()[0]
    everything = ds.radar_points(scene=scene, columns=["x", "passes_default_filters"])
    assert everything.height > 0 and everything["passes_default_filters"].null_count() == everything.height
    assert ds.radar_points(scene=scene, filtered=True).shape == (everything.height, 6)
    assert ds.radar_points(scene=scene, columns=["x"], filtered=True)["x"].to_list() == everything["x"].to_list()
    frame = ds.scan("frames").filter(pl.col("modality").cast(pl.String) == "radar").head(1).collect().row(0, named=True)
    raw = read_radar_pcd(short_radar_out.parent / "data" / frame["filename"])
    assert passes_default_filters(raw) is None and len(raw) > 0
    expected = np.stack([raw[name].astype(np.float64) for name in raw.dtype.names], axis=1)
    np.testing.assert_array_equal(ds.radar_points(frame["token"], filtered=True), expected)
