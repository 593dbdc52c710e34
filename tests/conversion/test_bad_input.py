"""Bad input: every kind of problem stops the conversion with exit code 1 and a message naming the file,
the record and the token; an existing or half-written OUT is never left looking complete."""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import polars as pl
import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main
from nuparquet.problems import MAX_REPORTED

V = SYNTH_VERSION


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    """A tiny metadata-only synthetic dataset: 1 scene x 4 samples."""
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("pristine") / "data"
    synthesize(root, scenes=1, samples_per_scene=4, seed=3, version=V)
    return root


@pytest.fixture
def root(pristine, tmp_path) -> Path:
    copy = tmp_path / "data"
    shutil.copytree(pristine / V, copy / V)
    return copy


def load(root: Path, table: str) -> list[dict]:
    return json.loads((root / V / f"{table}.json").read_text())


def save(root: Path, table: str, records) -> None:
    (root / V / f"{table}.json").write_text(json.dumps(records, indent=1))


def convert(root: Path, tmp_path: Path, capsys) -> tuple[int, str]:
    code = main(["convert", str(root), "--version", V, "--out", str(tmp_path / "out"), "--quiet"])
    captured = capsys.readouterr()
    assert not (tmp_path / "out").exists() or code == 0
    return code, captured.err + captured.out


def validate(root: Path, capsys) -> tuple[int, str]:
    code = main(["validate", str(root), "--version", V])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


def test_truncated_json_names_the_file(root, tmp_path, capsys):
    path = root / V / "sample_annotation.json"
    path.write_text(path.read_text()[: path.stat().st_size // 2])
    code, message = convert(root, tmp_path, capsys)
    assert code == 1
    assert "sample_annotation.json: not valid JSON at line" in message


def test_missing_table_names_the_file(root, tmp_path, capsys):
    (root / V / "ego_pose.json").unlink()
    code, message = convert(root, tmp_path, capsys)
    assert code == 1 and "ego_pose.json" in message and "missing" in message


def test_object_instead_of_array(root, tmp_path, capsys):
    save(root, "log", load(root, "log")[0])
    code, message = convert(root, tmp_path, capsys)
    assert code == 1 and "log.json" in message and "JSON object" in message


def test_missing_required_field_names_record_and_token(root, tmp_path, capsys):
    records = load(root, "sample")
    del records[2]["timestamp"]
    save(root, "sample", records)
    code, message = convert(root, tmp_path, capsys)
    assert code == 1
    assert f"sample.json[2] token={records[2]['token']}" in message and "timestamp" in message


def test_string_where_a_number_belongs(root, tmp_path, capsys):
    records = load(root, "sample_annotation")
    records[5]["num_lidar_pts"] = "many"
    save(root, "sample_annotation", records)
    code, message = convert(root, tmp_path, capsys)
    assert code == 1
    assert f"sample_annotation.json[5] token={records[5]['token']}" in message
    assert "num_lidar_pts" in message and "integer" in message


def test_non_integer_count_is_an_error_not_a_truncation(root, tmp_path, capsys):
    records = load(root, "sample_annotation")
    records[1]["num_radar_pts"] = 2.5
    save(root, "sample_annotation", records)
    code, message = convert(root, tmp_path, capsys)
    assert code == 1 and f"sample_annotation.json[1] token={records[1]['token']}" in message


def test_duplicate_token(root, tmp_path, capsys):
    records = load(root, "instance")
    records[1]["token"] = records[0]["token"]
    save(root, "instance", records)
    code, message = convert(root, tmp_path, capsys)
    assert code == 1 and f"instance.json[1] token={records[0]['token']}: duplicate token" in message


def test_a_second_keyframe_of_a_sensor_in_one_sample_is_refused_naming_both(root, tmp_path, capsys):
    """A sample holds one keyframe per channel (the devkit's `sample['data']` keeps one token per channel, the last
    in file order, while a first-in-order pairing would take the other): a sweep of LIDAR_TOP flagged as a
    keyframe of the sample it names is refused, the later of the two in sample_data.json named, with the first."""
    records = load(root, "sample_data")
    sensor = {r["token"]: r["channel"] for r in load(root, "sensor")}
    channel = {r["token"]: sensor[r["sensor_token"]] for r in load(root, "calibrated_sensor")}
    lidar = [i for i, r in enumerate(records) if channel[r["calibrated_sensor_token"]] == "LIDAR_TOP"]
    sweep = next(i for i in lidar[len(lidar) // 2:] if not records[i]["is_key_frame"])
    keyframe = next(i for i in lidar if records[i]["is_key_frame"]
                    and records[i]["sample_token"] == records[sweep]["sample_token"])
    records[sweep]["is_key_frame"] = True
    save(root, "sample_data", records)
    first, second = sorted([sweep, keyframe])
    code, message = convert(root, tmp_path, capsys)
    assert code == 1
    assert (f"sample_data.json[{second}] token={records[second]['token']}: is a second keyframe of LIDAR_TOP for "
            f"sample {records[sweep]['sample_token']} (the first is {records[first]['token']}): a sample holds one "
            "keyframe per channel") in message, message
    assert message.count("is a second keyframe") == 1  # the other channels' keyframes of that sample are single


# Every foreign key the issue lists: (table, field, record index to break).
FOREIGN_KEYS = [
    ("sample_data", "sample_token"), ("sample_data", "ego_pose_token"), ("sample_data", "calibrated_sensor_token"),
    ("calibrated_sensor", "sensor_token"), ("sample", "scene_token"), ("scene", "log_token"),
    ("scene", "first_sample_token"), ("scene", "last_sample_token"), ("sample_annotation", "sample_token"),
    ("sample_annotation", "instance_token"), ("sample_annotation", "visibility_token"),
    ("sample_annotation", "attribute_tokens"), ("instance", "category_token"),
    ("instance", "first_annotation_token"), ("instance", "last_annotation_token"), ("map", "log_tokens"),
    ("sample", "prev"), ("sample", "next"), ("sample_data", "prev"), ("sample_data", "next"),
    ("sample_annotation", "prev"), ("sample_annotation", "next"),
]


@pytest.mark.parametrize("table,field", FOREIGN_KEYS)
def test_dangling_foreign_key_names_file_record_and_token(root, tmp_path, capsys, table, field):
    records = load(root, table)
    index = len(records) // 2 if table not in ("scene", "map") else 0
    dangling = "f" * 32
    if isinstance(records[index][field], list):
        records[index][field] = records[index][field] + [dangling]
    else:
        records[index][field] = dangling
    save(root, table, records)
    code, message = validate(root, capsys)
    assert code == 1
    assert f"{table}.json[{index}] token={records[index]['token']}: {field} '{dangling}' does not resolve" in message
    code, message = convert(root, tmp_path, capsys)
    assert code == 1 and f"{table}.json[{index}]" in message


def _empty_means_none(table: str, field: str) -> bool:
    from nuparquet.schemas import table_schemas

    return next(f for f in table_schemas()[table].fields if f.name == field).empty_ok


@pytest.mark.parametrize("table,field", [(t, f) for t, f in FOREIGN_KEYS if f not in ("attribute_tokens", "log_tokens")
                                         and not _empty_means_none(t, f)])
def test_empty_string_foreign_key_outside_prev_next_is_dangling(root, capsys, table, field):
    """"" means "none" only where the schema says so (prev/next, visibility_token); elsewhere, e.g. an
    annotation's instance_token, it is a reference to nothing."""
    records = load(root, table)
    index = len(records) // 2 if table not in ("scene", "map") else 0
    records[index][field] = ""
    save(root, table, records)
    code, message = validate(root, capsys)
    assert code == 1
    assert f"{table}.json[{index}] token={records[index]['token']}: {field} '' does not resolve" in message


@pytest.mark.parametrize("bad", [[math.nan, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0]])
def test_bad_quaternion(root, tmp_path, capsys, bad):
    records = load(root, "ego_pose")
    records[3]["rotation"] = bad
    save(root, "ego_pose", records)
    code, message = convert(root, tmp_path, capsys)
    assert code == 1
    assert f"ego_pose.json[3] token={records[3]['token']}: rotation" in message and "unit quaternion" in message


def test_count_field_disagreeing_with_the_records(root, tmp_path, capsys):
    records = load(root, "scene")
    records[0]["nbr_samples"] += 1
    save(root, "scene", records)
    code, message = validate(root, capsys)
    assert code == 1 and f"scene.json[0] token={records[0]['token']}: nbr_samples" in message


def test_count_field_on_a_record_nothing_refers_to(root, capsys):
    """An instance with nbr_annotations 3 that no annotation names (its first/last point at another instance's
    annotations, so only the count is wrong); and a scene claiming one sample fewer than it has."""
    instances = load(root, "instance")
    lonely = dict(instances[0], token="e" * 32, nbr_annotations=3)
    save(root, "instance", instances + [lonely])
    scenes = load(root, "scene")
    scenes[0]["nbr_samples"] -= 1
    save(root, "scene", scenes)
    code, message = validate(root, capsys)
    assert code == 1
    assert (f"instance.json[{len(instances)}] token={'e' * 32}: nbr_annotations is 3 but 0 sample_annotation "
            "records refer to it") in message
    assert f"scene.json[0] token={scenes[0]['token']}: nbr_samples is {scenes[0]['nbr_samples']} but" in message


def test_allow_dangling_warns_of_each_dangling_reference_and_count_by_file_record_and_token(root):
    """`validate(allow_dangling=True)` in the test's process (the CLI's subprocess runs are invisible to mutmut):
    a scalar reference to nothing, a list of tokens with one absent, "" where it is a reference (sample_data's
    ego_pose_token) and where it means none (visibility_token, the first sample's prev), a count left wrong by
    the move, and an extra table no schema describes (`<table>_token`, `<table>_tokens`, and a field naming a
    table that is absent, which is not a reference). Each warning is compared with the walk of the JSON in plain
    Python (`trimmed_shapes.expected_findings`) and the edits made here."""
    import nuparquet
    from trimmed_shapes import expected_findings

    absent = "f" * 32
    annotations = load(root, "sample_annotation")
    moved, listed, none = 5, next(i for i, a in enumerate(annotations) if a["attribute_tokens"] and i > 5), 7
    lost_instance = annotations[moved]["instance_token"]
    annotations[moved]["instance_token"] = absent
    annotations[listed]["attribute_tokens"] = annotations[listed]["attribute_tokens"] + [absent]
    annotations[none]["visibility_token"] = ""
    save(root, "sample_annotation", annotations)
    sample_data = load(root, "sample_data")
    sample_data[3]["ego_pose_token"] = ""
    save(root, "sample_data", sample_data)
    attributes = [a["token"] for a in load(root, "attribute")]
    category = load(root, "category")[0]["token"]
    objects = [{"token": "a" * 32, "category_token": category, "sample_data_token": sample_data[0]["token"], "attribute_tokens": [attributes[0]],
                "surface_ann_token": absent},
               {"token": "b" * 32, "category_token": category, "sample_data_token": absent, "attribute_tokens": [], "surface_ann_token": absent},
               {"token": "c" * 32, "category_token": category, "sample_data_token": sample_data[1]["token"],
                "attribute_tokens": [attributes[1], absent, attributes[2]], "surface_ann_token": absent}]
    save(root, "object_ann", objects)

    references, counts = expected_findings(root / V)
    instances = load(root, "instance")
    lost = next(i for i, r in enumerate(instances) if r["token"] == lost_instance)
    assert sorted(references) == sorted([
        ("sample_annotation", "instance_token", "instance", moved, annotations[moved]["token"], absent, None),
        ("sample_annotation", "attribute_tokens", "attribute", listed, annotations[listed]["token"], absent,
         len(annotations[listed]["attribute_tokens"]) - 1),
        ("sample_data", "ego_pose_token", "ego_pose", 3, sample_data[3]["token"], "", None),
        ("object_ann", "sample_data_token", "sample_data", 1, "b" * 32, absent, None),
        ("object_ann", "attribute_tokens", "attribute", 2, "c" * 32, absent, 1)])
    stated = instances[lost]["nbr_annotations"]
    assert counts == [("instance", "nbr_annotations", "sample_annotation", lost, lost_instance, stated, stated - 1)]

    found = nuparquet.validate(root, V, allow_dangling=True)
    assert found.ok and all(w.warning and not w.omitted for w in found.warnings)
    expected = [(f"{t}.json", i, token, f"{field} '{reference}' does not resolve to a {target} record")
                for t, field, target, i, token, reference, _ in references]
    expected += [(f"{t}.json", i, token, f"{field} is {n} but {actual} {referring} records refer to it")
                 for t, field, referring, i, token, n, actual in counts]
    assert sorted((w.file, w.index, w.token, w.message) for w in found.warnings) == sorted(expected)
    strict = nuparquet.validate(root, V)  # the same data refused without the option (the extra table unchecked)
    assert sorted((p.file, p.index) for p in strict.problems) == sorted(
        (f, i) for f, i, *_ in expected if f != "object_ann.json")


def test_allow_dangling_conversion_counts_each_dangling_field_in_the_manifest_and_a_warning_line(root, tmp_path):
    """`convert(allow_dangling=True)` in the test's process: manifest.json `dangling` counts the findings by table and
    field, with their totals, as the walk of the JSON in plain Python (`trimmed_shapes.expected_findings`) and the
    edits made here count them, and one warning line says each count (singular for one)."""
    from collections import Counter

    import nuparquet
    from trimmed_shapes import expected_findings

    annotations = load(root, "sample_annotation")
    for i in (2, 5):
        annotations[i]["instance_token"] = "f" * 32
    save(root, "sample_annotation", annotations)
    sample_data = load(root, "sample_data")
    sample_data[3]["ego_pose_token"] = ""
    save(root, "sample_data", sample_data)
    references, counts = expected_findings(root / V)
    by_field = {("sample_annotation", "instance_token", "instance"): 2,
                ("sample_data", "ego_pose_token", "ego_pose"): 1}
    assert Counter((t, f, target) for t, f, target, *_ in references) == by_field
    assert counts  # the instances that lost their annotations: their nbr_annotations disagree

    manifest = nuparquet.convert(root, V, tmp_path / "out", allow_dangling=True)
    reported = manifest["dangling"]
    assert {(e["table"], e["field"], e["target"]): e["count"] for e in reported["references"]} == by_field
    assert reported["total_references"] == 3
    assert {(e["table"], e["field"]): e["count"] for e in reported["count_mismatches"]} == \
        dict(Counter((t, f) for t, f, *_ in counts))
    assert reported["total_count_mismatches"] == len(counts)
    accepted = "(accepted with --allow-dangling; each is listed in findings/)"
    warnings = manifest["warnings"]
    assert f"sample_annotation.json: 2 instance_token references name no instance record {accepted}" in warnings
    assert f"sample_data.json: 1 ego_pose_token reference names no ego_pose record {accepted}" in warnings


def test_allow_dangling_still_checks_every_count_when_a_counted_table_is_missing(root):
    """Everything at once: without scene.json the scene count cannot be checked, but the instance count still is;
    both the missing table (a problem) and the wrong nbr_annotations (a warning) are reported."""
    import nuparquet

    (root / V / "scene.json").unlink()
    instances = load(root, "instance")
    instances[2]["nbr_annotations"] += 1
    save(root, "instance", instances)
    actual = sum(a["instance_token"] == instances[2]["token"] for a in load(root, "sample_annotation"))
    found = nuparquet.validate(root, V, allow_dangling=True)
    assert [(p.file, p.message) for p in found.problems] == [
        ("scene.json", f"table scene is missing (expected {root / V / 'scene.json'})")]
    assert [(w.file, w.index, w.token, w.message) for w in found.warnings] == [
        ("instance.json", 2, instances[2]["token"],
         f"nbr_annotations is {actual + 1} but {actual} sample_annotation records refer to it")]


def test_problems_are_listed_all_at_once_with_a_bound(root, capsys):
    records = load(root, "sample_data")
    for r in records:
        r["calibrated_sensor_token"] = "0" * 32
    save(root, "sample_data", records)
    code, message = validate(root, capsys)
    assert code == 1
    assert message.count("does not resolve to a calibrated_sensor record") == 50
    assert f"sample_data.json: ... {len(records) - 50} more like the above" in message  # names the file
    assert f"\n{len(records)} problems found" in message  # the summary counts the ones not listed too


def test_exactly_the_bound_of_problems_lists_them_all_without_a_summary(root, capsys):
    records = load(root, "sample_data")
    for r in records[:50]:
        r["calibrated_sensor_token"] = "0" * 32
    save(root, "sample_data", records)
    code, message = validate(root, capsys)
    assert code == 1
    assert message.count("does not resolve to a calibrated_sensor record") == 50
    assert "more like the above" not in message and "\n50 problems found" in message


def test_more_warnings_than_the_bound_stay_warnings(root, tmp_path, capsys):
    """60 near-unit quaternions: 50 warnings listed and a summary line that is a warning too, not an error."""
    records = load(root, "ego_pose")
    assert len(records) > 60
    for r in records[:60]:
        r["rotation"] = [x * 0.99997 for x in r["rotation"]]
    save(root, "ego_pose", records)
    code, message = convert(root, tmp_path, capsys)
    assert code == 0, message
    warnings = json.loads((tmp_path / "out" / "manifest.json").read_text())["warnings"]
    assert len(warnings) == 51 and any("10 more like the above" in w for w in warnings)


def test_missing_sensor_files_are_not_an_error(root, tmp_path, capsys):
    assert not (root / "samples").exists()  # metadata only
    code, _ = convert(root, tmp_path, capsys)
    assert code == 0


def test_existing_out_is_refused_and_kept(root, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    code = main(["convert", str(root), "--version", V, "--out", str(out), "--quiet"])
    assert code == 2 and "--overwrite" in capsys.readouterr().err
    assert (out / "keep.txt").read_text() == "mine"


def _replace_builder(monkeypatch, name: str, build) -> None:
    """Swap one registered builder's build function (the conversion reads the registry at call time)."""
    import dataclasses

    import nuparquet.conversion.pipeline as convert_module
    from nuparquet.conversion import registry

    builders = tuple(dataclasses.replace(b, build=build) if b.name == name else b for b in registry.BUILDERS)
    monkeypatch.setattr(convert_module, "BUILDERS", builders)


def test_interrupted_conversion_leaves_nothing_complete_looking(root, tmp_path, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    _replace_builder(monkeypatch, "scenes", interrupted)
    out = tmp_path / "out"
    assert main(["convert", str(root), "--version", V, "--out", str(out), "--quiet"]) == 130
    assert not out.exists()
    assert list(tmp_path.glob(".out*")) == []  # the temporary sibling is cleaned up


def test_failed_overwrite_keeps_the_previous_output(root, tmp_path, monkeypatch):
    out = tmp_path / "out"
    assert main(["convert", str(root), "--version", V, "--out", str(out), "--quiet"]) == 0
    before = (out / "manifest.json").read_text()
    _replace_builder(monkeypatch, "instances", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt))
    assert main(["convert", str(root), "--version", V, "--out", str(out), "--overwrite", "--quiet"]) == 130
    assert (out / "manifest.json").read_text() == before


def test_successful_overwrite_leaves_the_new_output_and_nothing_of_the_old(irregular_root, tmp_path):
    """Convert the annotated version, then --overwrite with the version whose annotation tables are empty: the
    annotations are gone (counted from the JSON), a file only the old output had is gone, the files are those of
    a fresh conversion, and no temporary sibling is left."""
    from conftest import IRREGULAR_EMPTY_VERSION, IRREGULAR_VERSION

    out, fresh = tmp_path / "out", tmp_path / "fresh"
    assert main(["convert", str(irregular_root), "--version", IRREGULAR_VERSION, "--out", str(out), "--quiet"]) == 0
    old_annotations = len(json.loads((irregular_root / IRREGULAR_VERSION / "sample_annotation.json").read_text()))
    assert pl.read_parquet(out / "annotations" / "*.parquet").height == old_annotations > 0
    (out / "annotations" / "stale-part.parquet").write_bytes(b"old")
    assert main(["convert", str(irregular_root), "--version", IRREGULAR_EMPTY_VERSION, "--out", str(out),
                 "--overwrite", "--quiet"]) == 0
    assert json.loads((out / "manifest.json").read_text())["source"]["version"] == IRREGULAR_EMPTY_VERSION
    assert not (out / "annotations" / "stale-part.parquet").exists()
    assert pl.read_parquet(out / "annotations" / "*.parquet").height == 0
    assert main(["convert", str(irregular_root), "--version", IRREGULAR_EMPTY_VERSION, "--out", str(fresh),
                 "--quiet"]) == 0
    listing = lambda root: sorted(str(p.relative_to(root)) for p in root.rglob("*"))  # noqa: E731
    assert listing(out) == listing(fresh)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fresh", "out"]


@pytest.mark.parametrize("table,field,value,expected", [
    ("sample_annotation", "size", [1.0, "x", 2.0], "must be a list of numbers"),
    ("sample_annotation", "translation", [1.0, 2.0], "must have 3 numbers"),
    ("sample_annotation", "translation", [1.0, 2.0, 3.0, 4.0], "must have 3 numbers"),  # too long, too
    ("ego_pose", "rotation", [1.0, 0.0, 0.0, 0.0, 0.0], "must have 4 numbers"),
    ("calibrated_sensor", "camera_intrinsic", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]],
     "must have 3x3 numbers or be []"),
    ("calibrated_sensor", "camera_intrinsic", [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
     "must have 3x3 numbers or be []"),
    ("calibrated_sensor", "camera_intrinsic", [[1.0, 0.0], [0.0, 1.0]], "must have 3x3 numbers or be []"),
    ("sample_data", "is_key_frame", "yes", "must be a boolean"),
    ("sensor", "channel", 5, "must be a string"),
])
def test_wrong_json_type_or_shape_names_the_record(root, capsys, table, field, value, expected):
    records = load(root, table)
    index = 1
    records[index][field] = value
    save(root, table, records)
    code, message = validate(root, capsys)
    assert code == 1
    assert f"{table}.json[{index}] token={records[index]['token']}: field '{field}' {expected}" in message


@pytest.mark.parametrize("norm, accepted", [(0.99997, True), (1.0009, True), (1.0011, False), (0.99, False)])
def test_near_unit_quaternions_are_accepted_with_a_warning(root, tmp_path, capsys, norm, accepted):
    """Quaternions written to 4 decimals (norm 0.99997) are unit to the devkit (pyquaternion normalises): accepted
    with a warning naming the record; beyond 1e-3 of unit they stay errors."""
    records = load(root, "ego_pose")
    q = [x * norm for x in records[3]["rotation"]]
    records[3]["rotation"] = q
    save(root, "ego_pose", records)
    out = tmp_path / "out"
    code = main(["convert", str(root), "--version", V, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    where = f"ego_pose.json[3] token={records[3]['token']}: rotation"
    if accepted:
        assert code == 0 and f"warning: {where}" in err and "accepted and normalised" in err
        manifest = json.loads((out / "manifest.json").read_text())
        assert any(where in w for w in manifest["warnings"])
    else:
        assert code == 1 and where in err and "not a finite unit quaternion" in err and not out.exists()


def test_output_at_or_inside_the_dataroot_is_refused_and_nothing_is_deleted(root, tmp_path, capsys):
    before = sorted(p.name for p in (root / V).iterdir())
    for out in (root, root / "parquet", root / V):
        code = main(["convert", str(root), "--version", V, "--out", str(out), "--overwrite", "--quiet"])
        assert code == 2 and "write the output somewhere else" in capsys.readouterr().err
    assert sorted(p.name for p in (root / V).iterdir()) == before and not (root / "parquet").exists()


def test_dataroot_inside_the_output_is_refused(root, tmp_path, capsys):
    code = main(["convert", str(root), "--version", V, "--out", str(root.parent), "--overwrite", "--quiet"])
    assert code == 2 and "contains the dataroot" in capsys.readouterr().err
    assert (root / V / "sample.json").exists()


def test_export_json_into_the_converted_output_is_refused(root, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["convert", str(root), "--version", V, "--out", str(out), "--quiet"]) == 0
    before = sorted(str(p) for p in out.rglob("*"))
    for target in (out, out / "json"):
        assert main(["export-json", str(out), "--out", str(target), "--overwrite"]) == 2
        assert "write the output somewhere else" in capsys.readouterr().err
    assert sorted(str(p) for p in out.rglob("*")) == before


def test_an_output_that_appears_during_the_conversion_is_never_replaced(root, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"

    def appear_then_build(ctx):
        out.mkdir()
        (out / "theirs.txt").write_text("someone else's")
        return original(ctx)

    from nuparquet.conversion import registry

    original = next(b.build for b in registry.BUILDERS if b.name == "instances")
    _replace_builder(monkeypatch, "instances", appear_then_build)
    assert main(["convert", str(root), "--version", V, "--out", str(out), "--quiet"]) == 2
    assert "appeared while the output was being written" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["theirs.txt"]
    assert list(tmp_path.glob(".out*")) == []  # no partial folder left behind


def test_echoed_values_are_cut_and_escaped(root, tmp_path, capsys):
    """A 100,000-character token with a terminal escape sequence: the message names the record, quotes at most
    about 100 characters of it, and no control character reaches the terminal."""
    records = load(root, "sample")
    records[1]["scene_token"] = "\x1b[31m" + "x" * 100_000
    save(root, "sample", records)
    records = load(root, "sensor")
    records[0]["channel"] = 7
    save(root, "sensor", records)
    assert main(["validate", str(root), "--version", V, "--quiet"]) == 1
    out = capsys.readouterr().out
    assert "sample.json[1]" in out and "\\x1b[31m" in out and "\x1b" not in out
    assert max(len(line) for line in out.splitlines()) < 400
    assert "(100,005 characters)" in out


@pytest.mark.parametrize("edit, position", [
    (lambda text: text.replace("}]", "},\n]", 1) if text.rstrip().endswith("}]") else text[:-2] + ",\n]\n",
     "not valid JSON at line"),
    (lambda text: text.replace('"timestamp": ', '"timestamp": nan, "x": ', 1), "not valid JSON at line 4, column 14"),
])
def test_invalid_json_that_a_lenient_parser_would_accept_is_refused_with_its_position(root, tmp_path, capsys, edit, position):
    path = root / V / "sample.json"
    path.write_text(edit(path.read_text()))
    assert main(["convert", str(root), "--version", V, "--out", str(tmp_path / "out"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "sample.json: " + position in err and not (tmp_path / "out").exists()


def test_nan_and_infinity_literals_are_valid_json_here(root, tmp_path):
    """Python's json (and the devkit) read NaN and Infinity: a float field holding them converts and comes back."""
    path = root / V / "ego_pose.json"
    records = json.loads(path.read_text())
    records[0]["extra"] = [math.nan, math.inf, -math.inf]
    path.write_text(json.dumps(records))
    assert main(["convert", str(root), "--version", V, "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert main(["export-json", str(tmp_path / "out"), "--out", str(tmp_path / "back"), "--quiet"]) == 0
    again = json.loads((tmp_path / "back" / V / "ego_pose.json").read_text())
    assert json.dumps(again[0]) == json.dumps(records[0])


@pytest.mark.parametrize("table, key", [("sample_data", "timestamp"), ("sample_data", "token"),
                                        ("ego_pose", "translation")])
def test_a_duplicate_key_in_a_record_is_named_by_its_0_based_index_and_token(root, tmp_path, capsys, table, key):
    """Python's json keeps a repeated key's last value, DuckDB refuses it: refused, with the index every other
    message uses (DuckDB counts records from 1) and the record's token."""
    records = load(root, table)
    index = len(records) - 3
    token = records[index]["token"]
    text = json.dumps(records, indent=1)
    at = text.index(f'"token": "{token}"')
    repeated = json.dumps(records[index][key])  # a value of the right type: only the repetition is wrong
    (root / V / f"{table}.json").write_text(text[:at] + f'"{key}": {repeated}, ' + text[at:])
    code, message = convert(root, tmp_path, capsys)
    assert code == 1
    assert f'{table}.json[{index}] token={token}: record has duplicate key "{key}"' in message


@pytest.mark.parametrize("table, index, field, value, message", [
    ("sample_data", 3, "width", 2**70, "field 'width' must be an integer within the 64-bit range, got 1180591620717411303424"),
    ("sample_data", 3, "width", 2**64 - 1, "field 'width' must be an integer within the 64-bit range, got 18446744073709551615"),
    ("sample", 1, "timestamp", 2**70, "field 'timestamp' must be an integer within the 64-bit range, got 1180591620717411303424"),
    ("sample_data", 4, "timestamp", 2**63, "field 'timestamp' must be an integer within the 64-bit range, got 9223372036854775808"),
    ("ego_pose", 2, "timestamp", math.nan, "field 'timestamp' must be an integer within the 64-bit range, got NaN"),
    ("sample_data", 5, "height", -1, "height -1 must be >= 0"),
    ("sample_annotation", 2, "size", [-1.0, 2.0, math.inf], "size [-1.0, 2.0, inf] must be finite and >= 0"),
    ("sample_annotation", 6, "translation", [math.nan, 0.0, 0.0], "translation [nan, 0.0, 0.0] must be finite"),
    ("ego_pose", 7, "translation", [0.0, -math.inf, 0.0], "translation [0.0, -inf, 0.0] must be finite"),
    ("calibrated_sensor", 1, "translation", [0.0, 0.0, math.nan], "translation [0.0, 0.0, nan] must be finite"),
])
def test_values_that_cannot_be_kept_or_used_are_named_by_validate_and_convert(root, tmp_path, capsys, table, index,
                                                                              field, value, message):
    """Integers beyond int64 would change (a double) or not fit; NaN sizes and positions break every box and pose.
    Each is named with the record's 0-based index and token, by validate as by convert."""
    records = load(root, table)
    records[index][field] = value
    save(root, table, records)
    where = f"{table}.json[{index}] token={records[index]['token']}: {message}"
    where = re.compile(re.escape(where) + "$", re.M)  # the whole message ("must be finite", not "... and >= 0")
    code, out = validate(root, capsys)
    assert code == 1 and re.search(where, out)
    code, out = convert(root, tmp_path, capsys)
    assert code == 1 and re.search(where, out)


@pytest.mark.parametrize("value", [1e21, 2**63 - 1])
def test_a_float_literal_or_the_largest_int64_in_an_integer_field_comes_back_exactly(root, tmp_path, capsys, value):
    records = load(root, "sample_data")
    records[3]["width"] = value
    save(root, "sample_data", records)
    code, out = convert(root, tmp_path, capsys)
    assert code == 0, out
    assert main(["export-json", str(tmp_path / "out"), "--out", str(tmp_path / "back"), "--quiet"]) == 0
    again = json.loads((tmp_path / "back" / V / "sample_data.json").read_text())
    assert json.dumps(again) == json.dumps(records)


def test_a_field_differing_from_another_only_in_case_is_named_with_its_record(root, tmp_path, capsys):
    records = load(root, "sample")
    records[1]["Token"] = "abc"
    save(root, "sample", records)
    code, out = convert(root, tmp_path, capsys)
    assert code == 1 and "Traceback" not in out
    assert (f"sample.json[1] token={records[1]['token']}: fields 'token' and 'Token' differ only in case; Parquet "
            "columns as DuckDB and Spark read them cannot hold both (rename one)\n") in out


def test_a_missing_version_folder_lists_the_folders_holding_tables(tmp_path):
    from nuparquet.errors import UsageError
    from nuparquet.sources.tables import version_dir

    (tmp_path / "v1.0-mini").mkdir()
    (tmp_path / "v1.0-mini" / "scene.json").write_text("[]")
    (tmp_path / "maps").mkdir()  # a folder without JSON tables is not a version
    (tmp_path / "samples.json").write_text("[]")  # nor is a file
    (tmp_path / "can_bus").mkdir()  # nor a folder of other JSON files (the CAN bus expansion, the map's)
    (tmp_path / "can_bus" / "scene-0001_pose.json").write_text("[]")
    (tmp_path / "maps" / "boston-seaport.json").write_text("{}")
    with pytest.raises(UsageError) as error:
        version_dir(tmp_path, "v1.0-trainval")
    assert str(error.value) == f"version folder {tmp_path / 'v1.0-trainval'} does not exist; versions found: v1.0-mini"
    (tmp_path / "v1.0-test").mkdir()  # two versions: listed in name order, separated by a comma
    (tmp_path / "v1.0-test" / "sample.json").write_text("[]")
    with pytest.raises(UsageError) as error:
        version_dir(tmp_path, "v1.0-trainval")
    assert str(error.value) == (f"version folder {tmp_path / 'v1.0-trainval'} does not exist; "
                                "versions found: v1.0-mini, v1.0-test")
    with pytest.raises(UsageError) as error:
        version_dir(tmp_path / "maps", "v1.0-trainval")
    assert str(error.value) == f"version folder {tmp_path / 'maps' / 'v1.0-trainval'} does not exist"


@pytest.mark.parametrize("table,field,expected", [
    ("sample_annotation", "translation", "must have 3 numbers"),
    ("sample_annotation", "size", "must have 3 numbers"),
    ("sample_annotation", "rotation", "must have 4 numbers"),
    ("ego_pose", "translation", "must have 3 numbers"),
    ("calibrated_sensor", "rotation", "must have 4 numbers"),
])
def test_an_empty_list_in_a_fixed_size_field_is_refused_by_validate_and_convert(root, tmp_path, capsys, table,
                                                                                 field, expected):
    """`[]` is a list of the right kind with no numbers: only a field declared so (`camera_intrinsic`, a lidar's or
    radar's) may be empty; in translation, size or rotation it is refused naming the record and the field, by the
    validator and by the converter's compiled scanner alike."""
    records = load(root, table)
    index = 2
    records[index][field] = []
    save(root, table, records)
    named = f"{table}.json[{index}] token={records[index]['token']}: field '{field}' {expected}"
    code, message = validate(root, capsys)
    assert code == 1 and named in message
    code, message = convert(root, tmp_path, capsys)
    assert code == 1 and named in message


def test_an_empty_camera_intrinsic_is_a_non_camera_sensors_and_converts(root, tmp_path, capsys):
    """The one fixed-size field declared as possibly empty: a lidar's `camera_intrinsic` `[]` (as nuScenes writes
    it) validates and converts, stored as null in the Array(Float64, 9) column (export-json writes `[]` back)."""
    records = load(root, "calibrated_sensor")
    sensors = {s["token"]: s for s in load(root, "sensor")}
    lidar = next(i for i, r in enumerate(records) if sensors[r["sensor_token"]]["modality"] == "lidar")
    assert records[lidar]["camera_intrinsic"] == []  # the generator writes nuScenes' own []
    assert validate(root, capsys)[0] == 0
    code, _ = convert(root, tmp_path, capsys)
    assert code == 0
    table = pl.read_parquet(tmp_path / "out" / "tables" / "calibrated_sensor")
    assert table.schema["camera_intrinsic"] == pl.Array(pl.Float64, 9)
    assert table.filter(pl.col("token") == records[lidar]["token"])["camera_intrinsic"].to_list() == [None]


@pytest.mark.parametrize("dangling", [MAX_REPORTED, MAX_REPORTED + 1])
def test_allow_dangling_lists_exactly_the_bound_of_one_field_without_a_summary(root, dangling):
    """`validate(allow_dangling=True)` with exactly the warning bound of dangling references in one field lists
    every one and adds no "0 more like the above"; one more lists the bound and a summary of 1."""
    import nuparquet

    records = load(root, "sample_data")
    assert len(records) > dangling
    for r in records[:dangling]:
        r["calibrated_sensor_token"] = "0" * 32
    save(root, "sample_data", records)
    found = nuparquet.validate(root, V, allow_dangling=True)
    assert found.ok
    listed = [w for w in found.warnings if w.file == "sample_data.json" and not w.omitted]
    summaries = [w for w in found.warnings if w.omitted]
    assert [w.index for w in listed] == list(range(MAX_REPORTED))
    assert all("calibrated_sensor_token '" + "0" * 32 + "' does not resolve" in w.message for w in listed)
    if dangling == MAX_REPORTED:
        assert summaries == [] and not any("more like the above" in w.message for w in found.warnings)
    else:
        assert [(w.message, w.omitted) for w in summaries] == [("1 more like the above", 1)]
