"""nuparquet.devkit.NuScenes against nuscenes-devkit's NuScenes: the tables, their records (values, Python types, key
order, list order), the reverse indexes, get / getind / field2token, start-up and the errors, on the synthetic sets
(the irregular profile and its empty-annotation version, the irregular JSON layouts, the labelled set) and the real
extract."""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path

import numpy as np
import pytest

from devkit_pairs import DATASETS, open_pair
from devkit_same import assert_same, differences
from conftest import SYNTH_VERSION
from nuparquet.devkit import NotServed, NuScenes, ReadOnly
from nuparquet.errors import UsageError


@pytest.fixture(scope="module", params=list(DATASETS))
def pair(request, devkit):
    return open_pair(request, devkit, request.param)


def without_masks(records) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "mask"} for r in records]


def test_every_table_holds_the_devkits_records_in_file_order_with_their_types_and_key_order(pair):
    assert pair.ours.table_names == pair.theirs.table_names
    for name in pair.theirs.table_names:
        ours, theirs = list(getattr(pair.ours, name)), getattr(pair.theirs, name)
        if name == "map":
            assert [type(r["mask"]).__name__ for r in ours] == ["MapMask"] * len(ours)
            assert [list(r) for r in ours] == [list(r) for r in theirs]
            ours, theirs = without_masks(ours), without_masks(theirs)
        assert_same(ours, theirs, name)
    if hasattr(pair.theirs, "image_annotations"):
        assert_same(list(pair.ours.image_annotations), pair.theirs.image_annotations, "image_annotations")
    else:
        assert not hasattr(pair.ours, "image_annotations")


def test_the_layouts_set_reaches_the_records_column_types_alone_would_get_wrong(layouts_root, devkit):
    theirs = devkit.NuScenes(SYNTH_VERSION, dataroot=str(layouts_root), verbose=False)
    assert any("width" not in r for r in theirs.sample_data)  # absent keys
    assert any(isinstance(r.get("width"), float) and np.isnan(r["width"]) for r in theirs.sample_data)
    assert any(type(r["timestamp"]) is float for r in theirs.sample_data)
    assert any(list(r)[0] != "token" for r in theirs.sample)  # another key order
    assert any(type(x) is int for r in theirs.calibrated_sensor for x in r["rotation"])
    assert any("extra" in r for r in theirs.sample_data)
    assert theirs.log[0]["map_token"] != "only here" and list(theirs.log[0])[-1] == "map_token"
    assert len(theirs.image_annotations) == 6


def test_get_returns_the_tables_record_object_and_getind_its_index(pair):
    for name in pair.theirs.table_names:
        theirs = getattr(pair.theirs, name)
        for i in sorted({0, len(theirs) // 2, len(theirs) - 1}):
            if not len(theirs):
                continue
            token = theirs[i]["token"]
            assert pair.ours.getind(name, token) == pair.theirs.getind(name, token) == i
            assert type(pair.ours.getind(name, token)) is int
            record = pair.ours.get(name, token)
            assert record is getattr(pair.ours, name)[i] is pair.ours.get(name, token)
            if name != "map":
                assert_same(record, pair.theirs.get(name, token), f"{name} {token}")


def test_unknown_tokens_are_key_errors_and_unknown_tables_assertions_as_in_the_devkit(pair):
    for nusc in (pair.theirs, pair.ours):
        with pytest.raises(KeyError):
            nusc.get("sample", "no-such-token")
        with pytest.raises(KeyError):
            nusc.getind("sample", "no-such-token")
        with pytest.raises(AssertionError, match="Table not_a_table not found"):
            nusc.get("not_a_table", "x")
    with pytest.raises(KeyError):
        pair.ours.get("sample", None)


FIELD_QUERIES = [
    ("scene", "name", "scene-0002"), ("scene", "name", "scene-9999"), ("sample_data", "is_key_frame", True),
    ("sample_data", "is_key_frame", 1), ("sample_data", "is_key_frame", 1.0), ("sample_data", "is_key_frame", "True"),
    ("sample_data", "channel", "CAM_FRONT"), ("sample_data", "sensor_modality", "radar"), ("sample_data", "width", 1600),
    ("sample_data", "fileformat", "jpg"), ("sample_data", "height", None), ("sample_annotation", "visibility_token", "4"),
    ("sample_annotation", "visibility_token", ""), ("sample_annotation", "num_radar_pts", 0),
    ("sample_annotation", "num_lidar_pts", 3.0), ("sample_annotation", "attribute_tokens", []),
    ("sample_annotation", "category_name", "vehicle.car"), ("calibrated_sensor", "camera_intrinsic", []),
    ("category", "index", 1), ("log", "location", "singapore-onenorth"), ("sample", "prev", ""),
    ("visibility", "level", "v60-80"), ("sample_annotation", "num_lidar_pts", float("nan")),
]


def test_field2token_finds_what_the_devkits_linear_scan_finds(pair):
    queries = FIELD_QUERIES + [("sample_annotation", "instance_token", r["instance_token"])
                               for r in pair.theirs.sample_annotation[:2]]
    queries += [("sample", "timestamp", r["timestamp"]) for r in pair.theirs.sample[:2]]
    queries += [("ego_pose", "timestamp", float(r["timestamp"])) for r in pair.theirs.ego_pose[5:6]]
    for table, field, query in queries:
        try:
            expected = pair.theirs.field2token(table, field, query)
        except KeyError as exc:  # a record without the field (the layouts set): the devkit fails, so must we
            with pytest.raises(KeyError, match=str(exc)):
                pair.ours.field2token(table, field, query)
            continue
        got = pair.ours.field2token(table, field, query)
        assert got == expected, (table, field, query)
    if hasattr(pair.theirs, "image_annotations"):  # not in table_names, but field2token reaches it
        token = pair.theirs.image_annotations[2]["sample_annotation_token"]
        assert pair.ours.field2token("image_annotations", "sample_annotation_token", token) == \
            pair.theirs.field2token("image_annotations", "sample_annotation_token", token) != []
    matched = sum(bool(pair.theirs.field2token(t, f, q)) for t, f, q in FIELD_QUERIES if _has_field(pair, t, f))
    assert matched >= 8  # the queries reach matches, not only empty answers


def _has_field(pair, table, field) -> bool:
    return all(field in r for r in getattr(pair.theirs, table))


def test_tables_index_slice_and_iterate_like_the_devkits_lists(pair):
    for name in ("sample", "sample_annotation", "scene", "sample_data"):
        ours, theirs = getattr(pair.ours, name), getattr(pair.theirs, name)
        assert len(ours) == len(theirs)
        if not len(theirs):
            assert list(ours) == [] and ours[:] == []
            with pytest.raises(IndexError):
                ours[0]
            continue
        assert ours[-1] is ours[len(ours) - 1]
        assert_same(without_masks(ours[1:7:2]), without_masks(theirs[1:7:2]))
        assert_same(without_masks(ours[-3:]), without_masks(theirs[-3:]))
        assert ours[np.int64(0)] is ours[0]
        with pytest.raises(IndexError):
            ours[len(theirs)]
        with pytest.raises(IndexError):
            ours[-len(theirs) - 1]
        with pytest.raises(TypeError):
            ours["token"]
        if name in ("sample", "scene"):  # NaN-free records: list equality as Python compares dicts
            assert theirs[0] in ours and ours == theirs and not (ours != theirs)
            assert ours.index(theirs[-1]) == len(theirs) - 1


def test_tables_refuse_writes_and_records_keep_changes_like_the_devkits(layouts_out, layouts_root):
    nusc = NuScenes(SYNTH_VERSION, dataroot=str(layouts_root), parquet=layouts_out, verbose=False)
    for write in (lambda: nusc.sample.append({}), lambda: nusc.sample.__setitem__(0, {}), lambda: nusc.sample.pop(),
                  lambda: nusc.sample.sort(), lambda: nusc.sample.extend([])):
        with pytest.raises(ReadOnly, match="read-only"):
            write()
    with pytest.raises(TypeError):  # ReadOnly is a TypeError too, what a tuple would raise
        del nusc.sample[0]
    record = nusc.get("sample", nusc.sample[2]["token"])
    record["mine"] = 1
    assert nusc.sample[2]["mine"] == 1 and nusc.get("sample", record["token"]) is record


def test_start_up_reads_the_manifest_only_and_each_table_on_first_use(extract_out, extract_root):
    nusc = NuScenes("v1.0-mini-extract", dataroot=str(extract_root), parquet=extract_out, verbose=False)
    tables = nusc._tables
    assert not any(t.loaded for t in tables.values())
    assert len(nusc.sample_annotation) == 5049 and not tables["sample_annotation"].loaded  # lengths from the manifest
    nusc.get("scene", nusc.scene[0]["token"])
    assert {n for n, t in tables.items() if t.loaded} == {"scene"}
    nusc.sample_annotation[0]  # a record's category_name needs instance and category, not the other big tables
    assert {n for n, t in tables.items() if t.loaded} == {"scene", "sample_annotation", "instance", "category"}


def test_parquet_may_be_omitted_when_the_dataroot_is_the_output(extract_out, extract_root):
    nusc = NuScenes("v1.0-mini-extract", dataroot=str(extract_out), verbose=False)
    root = Path(extract_root).resolve()  # the manifest records the dataroot resolved (../shared may be a link)
    assert nusc.dataroot == str(root) and nusc.parquet == str(extract_out)
    token = nusc.sample_data[0]["token"]
    assert nusc.get_sample_data_path(token) == f"{root}/{nusc.sample_data[0]['filename']}"
    default = NuScenes("v1.0-mini-extract", parquet=extract_out, verbose=False)
    assert default.dataroot == str(root)


def test_a_version_that_was_not_converted_is_an_error_naming_both(extract_out):
    with pytest.raises(UsageError, match=r"'v1.0-trainval'.*'v1.0-mini-extract'"):
        NuScenes("v1.0-trainval", dataroot="/data/sets/nuscenes", parquet=extract_out, verbose=False)


def test_a_dataroot_that_is_not_an_output_needs_parquet_and_the_error_says_so(extract_root):
    with pytest.raises(UsageError, match="parquet=OUT.*nuparquet convert"):
        NuScenes("v1.0-mini-extract", dataroot=str(extract_root), verbose=False)


def test_a_map_resolution_below_the_maps_is_refused_as_by_the_devkit(extract_out):
    with pytest.raises(AssertionError, match="0.1 meter"):
        NuScenes("v1.0-mini-extract", parquet=extract_out, map_resolution=0.05, verbose=False)


def test_verbose_start_up_prints_the_devkits_table_sizes(extract_root, extract_out, devkit):
    def printed(make) -> list[str]:
        buffer = io.StringIO()
        with contextlib.redirect_stdout(buffer):
            make()
        return [line for line in buffer.getvalue().splitlines() if line.endswith(",")]

    theirs = printed(lambda: devkit.NuScenes("v1.0-mini-extract", dataroot=str(extract_root), verbose=True))
    ours = printed(lambda: NuScenes("v1.0-mini-extract", dataroot=str(extract_root), parquet=extract_out))
    assert ours == theirs and len(ours) == 13


def test_paths_colormap_and_lidarseg_mappings_equal_the_devkits(pair):
    ours, theirs = pair.ours, pair.theirs
    assert ours.table_root == theirs.table_root and ours.dataroot == theirs.dataroot and ours.version == theirs.version
    for record in theirs.sample_data[:50]:
        assert ours.get_sample_data_path(record["token"]) == theirs.get_sample_data_path(record["token"])
    assert list(ours.colormap.items()) == list(theirs.colormap.items())
    for name in ("lidarseg_idx2name_mapping", "lidarseg_name2idx_mapping"):
        assert hasattr(ours, name) == hasattr(theirs, name)
        if hasattr(theirs, name):
            assert list(getattr(ours, name).items()) == list(getattr(theirs, name).items())
    colormap = {name: (i, 2, 3) for i, name in enumerate(reversed(list(theirs.colormap)))}
    for given in (colormap, {"vehicle.car": (1, 2, 3)}):  # the second lacks classes lidarseg needs: both fail
        outcomes = []
        for make in (lambda: pair.theirs.__class__(pair.version, dataroot=str(pair.root), verbose=False,
                                                   colormap=dict(given)),
                     lambda: NuScenes(pair.version, dataroot=str(pair.root), parquet=pair.out, verbose=False,
                                      colormap=dict(given))):
            try:
                outcomes.append(list(make().colormap.items()))
            except KeyError as exc:
                outcomes.append(repr(exc))
        assert outcomes[0] == outcomes[1]


def test_labels_not_converted_are_absent_as_in_the_devkit_and_asking_says_what_to_convert(extract_root, extract_out):
    nusc = NuScenes("v1.0-mini-extract", dataroot=str(extract_root), parquet=extract_out, verbose=False)
    assert not hasattr(nusc, "lidarseg") and "lidarseg" not in nusc.table_names
    with pytest.raises(AssertionError, match="without lidarseg.json"):
        nusc.get("lidarseg", "x")
    with pytest.raises(NotServed, match="nuScenes-panoptic not installed"):
        nusc.list_panoptic_instances()
    with pytest.raises(NotServed, match="lidarseg"):
        nusc.get_sample_lidarseg_stats(nusc.sample[0]["token"])


def test_map_masks_are_the_devkits_at_every_resolution(synth_mapped_root, synth_out, devkit):
    points = np.random.default_rng(3).uniform(-50, 320, (2, 500))
    for resolution in (0.1, 0.3):
        theirs = devkit.NuScenes(SYNTH_VERSION, dataroot=str(synth_mapped_root), verbose=False,
                                 map_resolution=resolution)
        ours = NuScenes(SYNTH_VERSION, dataroot=str(synth_mapped_root), parquet=synth_out, verbose=False,
                        map_resolution=resolution)
        for mine, record in zip(ours.map, theirs.map):
            a, b = mine["mask"], record["mask"]
            assert (a.img_file, a.resolution, a.foreground, a.background) == (b.img_file, b.resolution, b.foreground,
                                                                              b.background)
            for dilation in (0.0, 2.0):
                assert_same(a.mask(dilation), b.mask(dilation))
                assert_same(a.is_on_mask(points[0], points[1], dilation), b.is_on_mask(points[0], points[1], dilation))
            assert_same(a.transform_matrix, b.transform_matrix)
            assert_same(a.to_pixel_coords(points[0], points[1]), b.to_pixel_coords(points[0], points[1]))
            on = a.is_on_mask(points[0], points[1])
            assert on.any() and not on.all()


def test_a_missing_map_png_keeps_the_record_readable_and_using_its_mask_names_the_file(synth_root, synth_out,
                                                                                      tmp_path):
    dataroot = tmp_path / "no-maps"
    dataroot.mkdir()
    nusc = NuScenes(SYNTH_VERSION, dataroot=str(dataroot), parquet=synth_out, verbose=False)
    record = nusc.map[0]
    assert record["filename"].startswith("maps/")
    with pytest.raises(NotServed, match=f"{dataroot}/maps/.*does not exist"):
        record["mask"].mask()


def test_log_without_a_map_is_refused_when_its_record_is_built_as_the_devkit_refuses_at_start_up(
        synth_root, tmp_path, devkit):
    import json

    from nuparquet.conversion import convert

    root = tmp_path / "data"
    shutil.copytree(synth_root / SYNTH_VERSION, root / SYNTH_VERSION)
    maps = json.loads((root / SYNTH_VERSION / "map.json").read_text())
    orphan = maps[0]["log_tokens"].pop()
    (root / SYNTH_VERSION / "map.json").write_text(json.dumps(maps))
    convert(root, SYNTH_VERSION, tmp_path / "out")
    nusc = NuScenes(SYNTH_VERSION, dataroot=str(root), parquet=tmp_path / "out", verbose=False)
    with pytest.raises(Exception, match=orphan):
        nusc.get("log", orphan)
    assert differences(nusc.scene[0]["name"], "scene-0001") == []


def test_a_pickled_copy_opens_the_same_output_and_answers_alike(extract_out, extract_root):
    import pickle

    nusc = NuScenes("v1.0-mini-extract", dataroot=str(extract_root), parquet=extract_out, verbose=False,
                    map_resolution=0.2)
    token = nusc.sample[3]["token"]
    copy = pickle.loads(pickle.dumps(nusc))
    assert (copy.version, copy.dataroot, copy.parquet, copy.map_resolution) == (
        nusc.version, nusc.dataroot, nusc.parquet, 0.2)
    assert_same(copy.get("sample", token), nusc.get("sample", token))
    assert copy.get("sample", token) is not nusc.get("sample", token)
    boxes = pickle.loads(pickle.dumps(nusc.get_boxes(nusc.sample[3]["data"]["CAM_FRONT"])))
    assert boxes and boxes[0].orientation == nusc.get_box(boxes[0].token).orientation


def test_without_kept_records_every_access_builds_an_equal_new_dict(extract_out, extract_root, devkit):
    theirs = devkit.NuScenes("v1.0-mini-extract", dataroot=str(extract_root), verbose=False)
    lean = NuScenes("v1.0-mini-extract", dataroot=str(extract_root), parquet=extract_out, verbose=False,
                    keep_records=False)
    for name in ("sample", "sample_annotation", "log", "calibrated_sensor"):
        assert_same(list(getattr(lean, name)), getattr(theirs, name), name)
    token = theirs.sample[5]["token"]
    first = lean.get("sample", token)
    first["mine"] = 1
    assert lean.get("sample", token) is not first and "mine" not in lean.get("sample", token)
    assert not lean._tables["sample"].by_token  # nothing held
    assert lean.field2token("scene", "name", "scene-0916") == theirs.field2token("scene", "name", "scene-0916")
    import pickle

    assert pickle.loads(pickle.dumps(lean))._keep_records is False


def test_a_log_listed_by_two_maps_takes_the_last_maps_token_as_the_devkit_does(synth_root, tmp_path, devkit):
    """The devkit builds log['map_token'] from a dict filled map by map: a log listed by two maps gets the later
    map's token."""
    import json

    from nuparquet.conversion import convert

    root = tmp_path / "data"
    for part in synth_root.iterdir():  # the tables, maps and label folders the devkit opens; not the sensor files
        if part.is_dir() and part.name not in ("samples", "sweeps"):
            shutil.copytree(part, root / part.name)
    maps = json.loads((root / SYNTH_VERSION / "map.json").read_text())
    assert len(maps) >= 2
    shared = maps[0]["log_tokens"][0]
    maps[-1]["log_tokens"].append(shared)
    (root / SYNTH_VERSION / "map.json").write_text(json.dumps(maps))
    convert(root, SYNTH_VERSION, tmp_path / "out")
    ours = NuScenes(SYNTH_VERSION, dataroot=str(root), parquet=tmp_path / "out", verbose=False)
    theirs = devkit.NuScenes(SYNTH_VERSION, dataroot=str(root), verbose=False)
    assert ours.get("log", shared)["map_token"] == theirs.get("log", shared)["map_token"] == maps[-1]["token"]
