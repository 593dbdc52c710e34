"""`nuparquet convert` of a nuImages dataroot: detected from its tables, written back byte for byte, objects/ and
surfaces/ equal to the JSON joined by hand, and every input it cannot convert exactly refused by file and field."""

from __future__ import annotations

import base64
import filecmp
import json
import shutil

import polars as pl
import pytest

from nuparquet.cli.main import main
from nuparquet.conversion import convert, validate
from nuparquet.errors import UsageError
from nuparquet.export.json_files import export_json
from nuparquet.problems import ProblemsFound
from nuparquet.synth import synthesize

VERSION = "v1.0-mini"


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return synthesize(tmp_path_factory.mktemp("nuim") / "root", scenes=2, samples_per_scene=2, seed=7,
                      family="nuimages", version=VERSION)


@pytest.fixture(scope="module")
def out(root, tmp_path_factory):
    target = tmp_path_factory.mktemp("nuim-out") / "out"
    convert(root, VERSION, target)
    return target


def _load(root, table):
    return json.loads((root / VERSION / f"{table}.json").read_text())


def test_a_nuimages_dataroot_is_detected_and_its_tables_come_back_byte_for_byte(root, out, tmp_path):
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["source"]["format"] == "nuimages"
    assert {"objects", "surfaces"} <= set(manifest["datasets"]) and "frames" not in manifest["datasets"]
    export_json(out, tmp_path / "back")
    names = sorted(p.name for p in (root / VERSION).iterdir())
    assert len(names) == 10
    for name in names:
        assert filecmp.cmp(root / VERSION / name, tmp_path / "back" / VERSION / name, shallow=False), name


def test_objects_are_the_json_joined_by_hand(root, out):
    sample_data = {r["token"]: r for r in _load(root, "sample_data")}
    samples = {r["token"]: r for r in _load(root, "sample")}
    logs = {r["token"]: r for r in _load(root, "log")}
    calibrations = {r["token"]: r for r in _load(root, "calibrated_sensor")}
    channels = {r["token"]: r["channel"] for r in _load(root, "sensor")}
    poses = {r["token"]: r for r in _load(root, "ego_pose")}
    categories = {r["token"]: r["name"] for r in _load(root, "category")}
    attributes = {r["token"]: r["name"] for r in _load(root, "attribute")}
    records = _load(root, "object_ann")
    rows = pl.read_parquet(out / "objects").to_dicts()
    assert [r["token"] for r in rows] == [r["token"] for r in sorted(records, key=lambda r: (
        r["sample_data_token"], records.index(r)))]
    for row in rows:
        record = records[row["file_index"]]
        image = sample_data[record["sample_data_token"]]
        calibration = calibrations[image["calibrated_sensor_token"]]
        pose = poses[image["ego_pose_token"]]
        assert row["token"] == record["token"] and row["bbox"] == record["bbox"]
        assert row["category_name"] == categories[record["category_token"]]
        assert row["attribute_names"] == [attributes[t] for t in record["attribute_tokens"]]
        assert row["log_location"] == logs[samples[image["sample_token"]]["log_token"]]["location"]
        assert row["channel"] == channels[calibration["sensor_token"]] and row["filename"] == image["filename"]
        assert row["camera_intrinsic"] == [v for r in calibration["camera_intrinsic"] for v in r]
        assert row["camera_distortion"] == calibration["camera_distortion"]
        assert row["ego_translation"] == pose["translation"] and row["ego_speed"] == pose["speed"]
        mask = record["mask"]
        assert row["mask_counts"] == (mask and mask["counts"])
        assert [row["mask_height"], row["mask_width"]] == (mask["size"] if mask else [None, None])
    assert {len(r["camera_distortion"]) for r in rows} | {len(c["camera_distortion"]) for c in calibrations.values()} \
        == {5, 6}  # the fisheye's six coefficients are kept


def test_surfaces_hold_every_surface_ann(root, out):
    rows = pl.read_parquet(out / "surfaces")
    records = _load(root, "surface_ann")
    assert sorted(rows["token"]) == sorted(r["token"] for r in records)
    assert set(rows["category_name"]) == {"flat.driveable_surface", "vehicle.ego"}
    assert rows["mask_area"].null_count() == sum(r["mask"] is None for r in records) == 1


def test_the_format_can_be_named_and_a_nuscenes_root_is_not_taken_for_nuimages(root, tmp_path):
    nuscenes = synthesize(tmp_path / "nusc", scenes=1, samples_per_scene=2, with_can_bus=False)
    with pytest.raises(ProblemsFound, match="table object_ann is missing"):
        convert(nuscenes, "v1.0-synth", tmp_path / "a", source_format="nuimages")
    assert convert(nuscenes, "v1.0-synth", tmp_path / "b")["source"]["format"] == "nuscenes"
    with pytest.raises(ProblemsFound, match="table scene is missing"):
        convert(root, VERSION, tmp_path / "c", source_format="nuscenes")
    with pytest.raises(UsageError, match="--source-format"):
        convert(root, VERSION, tmp_path / "d", source_format="nuimage")


def _edited(root, tmp_path, table, edit):
    copy = tmp_path / "edited"
    shutil.copytree(root / VERSION, copy / VERSION)
    records = _load(copy, table)
    edit(records)
    (copy / VERSION / f"{table}.json").write_text(json.dumps(records, indent=2))
    return copy


def _first_masked(records):
    return next(r for r in records if r["mask"] is not None)


def _recount(record, delta):
    """The mask's first run changed by `delta` pixels (its string re-encoded as pycocotools would)."""
    from nuparquet.synth.coco_rle import rle_string
    from nuparquet import rle

    counts = rle.counts_from_string(base64.b64decode(record["mask"]["counts"])).tolist()
    counts[0] += delta
    record["mask"]["counts"] = base64.b64encode(rle_string(counts)).decode()


@pytest.mark.parametrize("table,edit,expected", [
    ("object_ann", lambda rs: rs[1].__setitem__("bbox", [1, 2, 3]), r"object_ann.json\[1\].*'bbox' must have 4 numbers"),
    ("object_ann", lambda rs: rs[0].__setitem__("bbox", [1.5, 2, 3, 4]), r"object_ann.json.*'bbox' must be a list of 4 integers"),
    ("ego_pose", lambda rs: rs[3].__setitem__("speed", "fast"), r"ego_pose.json.*'speed' is a str where the others hold float"),
    ("object_ann", lambda rs: _recount(_first_masked(rs), 1), r"object_ann.json\[\d+\].*'mask' cannot be decoded: its runs cover"),
    ("surface_ann", lambda rs: _first_masked(rs)["mask"].__setitem__("counts", "!!!"), r"surface_ann.json\[\d+\].*'mask' cannot be decoded"),
    ("surface_ann", lambda rs: _first_masked(rs)["mask"].__setitem__("size", [2, 3]), r"surface_ann.json\[\d+\].*'mask'"),
    ("surface_ann", lambda rs: _first_masked(rs)["mask"].__setitem__("counts", 17),
     r"surface_ann.json\[\d+\].*'mask' cannot be decoded: its counts must be a base64 string, got 17"),
    ("object_ann", lambda rs: rs[2].__setitem__("category_token", "nope"), r"object_ann.json\[2\].*category_token 'nope' does not resolve"),
    ("sample_data", lambda rs: rs[3].pop("filename"), r"sample_data.json\[3\].*lacks filename"),
    ("calibrated_sensor", lambda rs: rs[0].__setitem__("camera_intrinsic", [[1, 0], [0, 1]]), r"calibrated_sensor.json\[0\].*'camera_intrinsic' must be a 3x3"),
    ("sample", lambda rs: rs.append(dict(rs[0])), r"sample.json\[\d+\].*duplicate token"),
    ("ego_pose", lambda rs: rs[2].__setitem__("timestamp", None), r"ego_pose.json\[2\].*field 'timestamp' is null"),
    ("object_ann", lambda rs: rs[3].__setitem__("sample_data_token", None),
     r"object_ann.json\[3\].*field 'sample_data_token' is null"),
])
def test_input_it_cannot_convert_exactly_is_refused_naming_file_and_field(root, tmp_path, table, edit, expected):
    edited = _edited(root, tmp_path, table, edit)
    with pytest.raises(ProblemsFound, match=expected):
        convert(edited, VERSION, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    assert not validate(edited, VERSION).ok


def test_a_mask_of_another_size_than_its_image_is_refused(root, tmp_path):
    from nuparquet.synth.coco_rle import encode
    import numpy as np

    def edit(records):
        _first_masked(records)["mask"] = encode(np.ones((4, 5), np.uint8))

    with pytest.raises(ProblemsFound, match=r"object_ann.json\[\d+\].*size \[4, 5\] but its image .* is 270 x 480"):
        convert(_edited(root, tmp_path, "object_ann", edit), VERSION, tmp_path / "out")


def test_the_cli_converts_renders_and_exports_coco(root, tmp_path, capsys):
    assert main(["convert", str(root), "--version", VERSION, "--out", str(tmp_path / "o"), "--source-format",
                 "nuimages", "--quiet"]) == 0
    sd = _load(root, "sample")[1]["key_camera_token"]
    assert main(["render", str(tmp_path / "o"), "--sample-data", sd, "--scale", "1", "--out",
                 str(tmp_path / "p.png")]) == 0
    import cv2

    assert cv2.imread(str(tmp_path / "p.png")).shape == (270, 480, 3)
    assert main(["export-coco", str(tmp_path / "o"), "--out", str(tmp_path / "c.json"), "--classes", "all"]) == 0
    coco = json.loads((tmp_path / "c.json").read_text())
    assert len(coco["images"]) == 4 and coco["annotations"]
    assert main(["export-coco", str(tmp_path / "o"), "--out", str(tmp_path / "c.json")]) == 2  # exists
    nuscenes = synthesize(tmp_path / "nusc", scenes=1, samples_per_scene=2, with_can_bus=False)
    convert(nuscenes, "v1.0-synth", tmp_path / "n")
    assert main(["export-coco", str(tmp_path / "n"), "--out", str(tmp_path / "x.json")]) == 2
    assert "not a nuImages conversion" in capsys.readouterr().err


def test_every_refusal_names_its_record_by_index_and_token(root, tmp_path):
    """Each problem of the refused tables says which record (0-based index and token), not only the file: a bad
    camera_intrinsic and a bbox of 3 numbers each name theirs."""
    import json

    edits = {"calibrated_sensor": lambda rs: rs[0].__setitem__("camera_intrinsic", [[1, 0], [0, 1]]),
             "object_ann": lambda rs: rs[1].__setitem__("bbox", [1, 2, 3])}
    edited = root
    for table, edit in edits.items():
        edited = _edited(edited, tmp_path / table, table, edit)
    records = {t: json.loads((edited / VERSION / f"{t}.json").read_text()) for t in edits}
    found = {(p.file, p.index, p.token) for p in validate(edited, VERSION).problems}
    assert ("calibrated_sensor.json", 0, records["calibrated_sensor"][0]["token"]) in found
    assert ("object_ann.json", 1, records["object_ann"][1]["token"]) in found


def test_the_manifest_records_each_source_file_by_size_and_mtime(root, out):
    """What a later `convert` compares to see the source changed: every nuImages JSON file by its size and mtime
    under the same keys the nuScenes reader writes (`sources.tables`)."""
    files = json.loads((out / "manifest.json").read_text())["source"]["files"]
    names = sorted(p.name for p in (root / VERSION).iterdir())
    assert sorted(files) == names
    for name in names:
        stat = (root / VERSION / name).stat()
        assert files[name] == {"bytes": stat.st_size, "mtime": stat.st_mtime}, name


def test_an_annotation_whose_image_dangles_keeps_its_row_under_allow_dangling(root, tmp_path):
    """--allow-dangling loses no annotation: an object_ann pointing at a sample_data that is not there is a row of
    objects/ with its own fields and nulls where the image's would be."""
    def edit(records):
        records[-1]["sample_data_token"] = "f" * 32

    edited = _edited(root, tmp_path, "object_ann", edit)
    with pytest.raises(ProblemsFound, match="sample_data_token"):
        convert(edited, VERSION, tmp_path / "refused")
    convert(edited, VERSION, tmp_path / "out", allow_dangling=True)
    records = _load(edited, "object_ann")
    rows = pl.read_parquet(tmp_path / "out" / "objects")
    assert rows.height == len(records)
    lost = rows.filter(pl.col("token") == records[-1]["token"]).to_dicts()
    assert len(lost) == 1
    assert lost[0]["bbox"] == records[-1]["bbox"] and lost[0]["category_name"] is not None
    assert lost[0]["filename"] is None and lost[0]["channel"] is None


def test_a_mask_table_without_any_mask_keeps_the_string_type_of_mask_counts(root, tmp_path):
    """A surface_ann whose every mask is null (a nuImages subset with no surfaces drawn) still writes mask_counts
    as the schema's string, not polars' null type, so scans of several outputs line up."""
    def edit(records):
        for record in records:
            record["mask"] = None

    convert(_edited(root, tmp_path, "surface_ann", edit), VERSION, tmp_path / "out")
    schema = pl.read_parquet_schema(tmp_path / "out" / "surfaces")
    assert schema["mask_counts"] == pl.String
    assert pl.read_parquet(tmp_path / "out" / "surfaces")["mask_counts"].null_count() == len(_load(root, "surface_ann"))
    from nuparquet.sources.nuimages import mask_facts

    # the facts themselves, before the writer's cast: the builders join and stack them with other tables' facts
    facts, problems = mask_facts(pl.DataFrame({"token": ["a", "b"], "mask": [None, None]},
                                              schema={"token": pl.String, "mask": pl.String}), "surface_ann.json")
    assert not problems and facts.schema["mask_counts"] == pl.String and facts["mask_area"].null_count() == 2


def test_the_package_names_are_the_functions_in_a_fresh_interpreter():
    # `masks` and `segmentation` name both a module and its function: the documented import gives the functions
    import subprocess
    import sys

    code = ("from nuparquet.nuimages import masks, segmentation, category_counts, attribute_counts\n"
            "print(masks.__module__, segmentation.__module__, category_counts.__name__, attribute_counts.__name__)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["nuparquet.nuimages.masks", "nuparquet.nuimages.segmentation", "category_counts",
                                   "attribute_counts"]
