"""Trimmed extracts and the other shapes of nuScenes-format data found in public repositories (issue 27, part 1),
built from the generator's output (`trimmed_shapes`). For each shape: the strict default converts it exactly or
refuses it with the message naming the count and the records; `--allow-dangling` converts it with N dangling
references reported, N counted in plain Python from the JSON (`trimmed_shapes.expected_findings`), every row of
the derived datasets kept with nulls exactly where a join has no partner, and every file back from export-json."""

from __future__ import annotations

import json
import re
from collections import Counter

import polars as pl
import pyarrow.parquet as pq
import pytest

from nuparquet.cli.main import main
from nuparquet.conversion import convert
from nuparquet.export.json_files import export_json
from nuparquet.schemas import dataset_schemas
from trimmed_shapes import SHAPES, VERSION, expected_findings, load, make, same_json, tables_of

DERIVED = ("frames", "annotations", "scenes", "instances")


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    from nuparquet.synth import synthesize

    return synthesize(tmp_path_factory.mktemp("trim-pristine") / "data", scenes=2, samples_per_scene=5, seed=21,
                      version=VERSION)


@pytest.fixture(scope="module")
def shaped(pristine, tmp_path_factory):
    """shaped(name) -> (shape, dataroot, OUT of `convert --allow-dangling`, its manifest), made once per shape."""
    made = {}

    def get(name: str):
        if name not in made:
            shape = next(s for s in SHAPES if s.name == name)
            root = make(pristine, tmp_path_factory.mktemp(name) / "data", shape)
            out = tmp_path_factory.mktemp(f"{name}-out") / "out"
            made[name] = shape, root, out, convert(root, VERSION, out, allow_dangling=True)
        return made[name]
    return get


@pytest.fixture(params=[s.name for s in SHAPES])
def case(request, shaped):
    return shaped(request.param)


def read(out, dataset: str) -> pl.DataFrame:
    return pl.read_parquet(out / dataset / "*.parquet")


def test_strict_default_converts_exactly_or_refuses_naming_every_problem(case, tmp_path, capsys):
    shape, root, _, _ = case
    dangling, mismatches = expected_findings(root / VERSION, with_2d=False)  # strict never checked the 2D tables
    out = tmp_path / "strict"
    code = main(["convert", str(root), "--version", VERSION, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    if shape.strict == "exact":
        assert code == 0 and not dangling and not mismatches, err
        export_json(out, tmp_path / "back")
        for path in sorted((root / VERSION).glob("*.json")):
            same_json(json.loads(path.read_text()), json.loads((tmp_path / "back" / VERSION / path.name).read_text()),
                      path.name)
            assert (tmp_path / "back" / VERSION / path.name).read_bytes() == path.read_bytes(), path.name
        return
    n = len(dangling) + len(mismatches)
    assert code == 1 and not out.exists()
    assert err.startswith(f"error: {n} problems in the input:\n"), err[:200]
    table, field, target, index, token, reference, _ = dangling[0]
    assert f"{table}.json[{index}] token={token}: {field} '{reference}' does not resolve to a {target} record" in err


def test_allow_dangling_reports_every_dangling_reference_by_table_and_field(case):
    _, root, out, manifest = case
    dangling, mismatches = expected_findings(root / VERSION)
    by_field = Counter((t, f, target) for t, f, target, *_ in dangling)
    reported = manifest["dangling"]
    assert {(e["table"], e["field"], e["target"]): e["count"] for e in reported["references"]} == dict(by_field)
    assert reported["total_references"] == len(dangling)
    assert {(e["table"], e["field"]): e["count"] for e in reported["count_mismatches"]} == \
        dict(Counter((t, f) for t, f, *_ in mismatches))
    assert reported["total_count_mismatches"] == len(mismatches)
    assert manifest["datasets"]["findings"]["rows"] == len(dangling) + len(mismatches)
    for (table, field, target), count in by_field.items():
        assert any(w.startswith(f"{table}.json: {count} {field} reference") and f"no {target} record" in w
                   for w in manifest["warnings"]), (table, field)


def test_findings_dataset_lists_each_one_with_its_record(case):
    _, root, out, _ = case
    dangling, mismatches = expected_findings(root / VERSION)
    findings = read(out, "findings")
    assert pq.read_schema(next((out / "findings").glob("*.parquet"))).remove_metadata().equals(
        dataset_schemas()["findings"].arrow_schema())
    refs = findings.filter(pl.col("kind") == "dangling_reference")
    assert sorted(refs.select("table", "field", "target", "record_index", "token", "reference", "position").rows()) == \
        sorted(dangling)
    assert refs["stated"].is_null().all() and refs["actual"].is_null().all()
    counts = findings.filter(pl.col("kind") == "count_mismatch")
    assert sorted(counts.select("table", "field", "target", "record_index", "token", "stated", "actual").rows()) == \
        sorted(mismatches)
    assert counts["reference"].is_null().all() and counts["position"].is_null().all()


def test_export_json_returns_every_file_exactly(case, tmp_path):
    _, root, out, manifest = case
    export_json(out, tmp_path / "back")
    originals = sorted(p.relative_to(root) for p in [*(root / VERSION).glob("*.json"), *(root / "can_bus").glob("*.json")])
    assert sorted(p.relative_to(tmp_path / "back") for p in (tmp_path / "back").rglob("*.json")
                  if "expansion" not in p.parts) == originals
    for path in originals:
        same_json(json.loads((root / path).read_text()), json.loads((tmp_path / "back" / path).read_text()), str(path))
        assert (root / path).read_bytes() == (tmp_path / "back" / path).read_bytes(), path  # byte for byte


def test_derived_datasets_keep_every_row_with_nulls_exactly_where_no_partner(case):
    _, root, out, _ = case
    t = tables_of(root / VERSION)
    tokens = {name: {r["token"] for r in records} for name, records in t.items()}
    by_token = {name: {r["token"]: r for r in records} for name, records in t.items()}
    sensor_of = {c["token"]: c["sensor_token"] for c in t["calibrated_sensor"]}

    def scene_of(sample_token):
        sample = by_token["sample"].get(sample_token)
        return by_token["scene"].get(sample["scene_token"]) if sample else None

    frames = {r["token"]: r for r in read(out, "frames").iter_rows(named=True)}
    assert set(frames) == tokens["sample_data"] and len(frames) == len(t["sample_data"])
    for sd in t["sample_data"]:
        row = frames[sd["token"]]
        assert (row["ego_translation"] is None) == (row["global_from_ego"] is None) == (sd["ego_pose_token"] not in tokens["ego_pose"])
        calibrated = sd["calibrated_sensor_token"] in tokens["calibrated_sensor"]
        assert (row["ego_from_sensor"] is None) == (not calibrated)
        camera = calibrated and by_token["calibrated_sensor"][sd["calibrated_sensor_token"]]["camera_intrinsic"] != []
        assert (row["image_from_global"] is None) == (not camera or row["ego_translation"] is None)
        assert (row["channel"] is None) == (not calibrated or sensor_of[sd["calibrated_sensor_token"]] not in tokens["sensor"])
        scene = scene_of(sd["sample_token"])
        assert row["scene_name"] == (scene["name"] if scene else None)
        assert row["log_location"] == (by_token["log"][scene["log_token"]]["location"] if scene and scene["log_token"] in tokens["log"] else None)

    annotations = {r["token"]: r for r in read(out, "annotations").iter_rows(named=True)}
    assert set(annotations) == tokens["sample_annotation"] and len(annotations) == len(t["sample_annotation"])
    attribute = {a["token"]: a["name"] for a in t["attribute"]}
    for a in t["sample_annotation"]:
        row = annotations[a["token"]]
        instance = by_token["instance"].get(a["instance_token"])
        category = by_token["category"].get(instance["category_token"]) if instance else None
        assert row["category_name"] == (category["name"] if category else None)
        sample = by_token["sample"].get(a["sample_token"])
        assert row["timestamp"] == (sample["timestamp"] if sample else None)
        assert row["attribute_names"] == [attribute.get(token) for token in a["attribute_tokens"]]

    scenes = {r["token"]: r for r in read(out, "scenes").iter_rows(named=True)}
    assert set(scenes) == tokens["scene"]
    for s in t["scene"]:
        for end in ("first", "last"):
            sample = by_token["sample"].get(s[f"{end}_sample_token"])
            assert scenes[s["token"]][f"{end}_timestamp"] == (sample["timestamp"] if sample else None)

    instances = {r["token"]: r for r in read(out, "instances").iter_rows(named=True)}
    assert set(instances) == tokens["instance"] and len(instances) == len(t["instance"])
    for i in t["instance"]:
        for end in ("first", "last"):
            annotation = by_token["sample_annotation"].get(i[f"{end}_annotation_token"])
            sample = by_token["sample"].get(annotation["sample_token"]) if annotation else None
            assert instances[i["token"]][f"{end}_timestamp"] == (sample["timestamp"] if sample else None)
        first = by_token["sample_annotation"].get(i["first_annotation_token"])
        scene = scene_of(first["sample_token"]) if first else None
        assert instances[i["token"]]["scene_name"] == (scene["name"] if scene else None)


def test_validate_allow_dangling_reports_the_same_findings_as_warnings(case, capsys):
    shape, root, _, _ = case
    dangling, mismatches = expected_findings(root / VERSION)
    assert main(["validate", str(root), "--version", VERSION, "--allow-dangling", "--max-problems", "100000",
                 "--quiet"]) == 0
    out = capsys.readouterr().out
    listed = Counter()
    for line in out.splitlines():
        found = re.match(r"warning: (\w+)\.json\[(\d+)\] token=\S+: (\w+) ", line)
        if found:
            listed[(found[1], found[3])] += 1
    omitted = Counter()
    for line in out.splitlines():
        found = re.match(r"(\w+)\.json: \.\.\. (\d+) more like the above", line)
        if found:
            omitted[found[1]] += int(found[2])
    expected = Counter((t, f) for t, f, *_ in dangling + mismatches)
    assert {key: min(n, 50) for key, n in expected.items()} == dict(listed)  # the first 50 of each, as strict lists them
    assert sum(omitted.values()) == sum(n - 50 for n in expected.values() if n > 50)
    total = len(dangling) + len(mismatches)
    assert out.splitlines()[-1].endswith(f"no problems ({total:,} dangling references and count mismatches accepted: "
                                         "--allow-dangling)" if total else "no problems")
    strict = main(["validate", str(root), "--version", VERSION, "--quiet"])
    strict_total = len(expected_findings(root / VERSION, with_2d=False)[0]) + len(mismatches)
    assert (strict, capsys.readouterr().out.splitlines()[-1]) == (
        (1, f"{strict_total} problems found") if shape.strict == "refused" else (0, strict_line(root)))


def strict_line(root) -> str:
    tables = tables_of(root / VERSION)
    return f"ok: {len(tables)} tables, {sum(map(len, tables.values())):,} records, no problems"


def test_a_clean_dataset_converts_the_same_with_allow_dangling_and_strict_writes_no_findings(pristine, tmp_path):
    strict = convert(pristine, VERSION, tmp_path / "strict")
    allowing = convert(pristine, VERSION, tmp_path / "allowing", allow_dangling=True)
    assert "dangling" not in strict and not (tmp_path / "strict" / "findings").exists()
    assert "findings" not in strict["datasets"] and strict["options"]["allow_dangling"] is False
    assert allowing["dangling"]["total_references"] == allowing["dangling"]["total_count_mismatches"] == 0
    assert read(tmp_path / "allowing", "findings").height == 0
    for name in DERIVED:
        schema = dataset_schemas()[name]
        written = {mode: pq.read_schema(next((tmp_path / mode / name).glob("*.parquet"))).remove_metadata()
                   for mode in ("strict", "allowing")}
        assert written["strict"].equals(schema.arrow_schema())  # the strict default: non-null as before
        assert written["allowing"].equals(schema.allowing_dangling().arrow_schema())
        assert [f.name for f in schema.fields if f.null_if_dangling and not written["allowing"].field(f.name).nullable] == []
        assert read(tmp_path / "strict", name).equals(read(tmp_path / "allowing", name)), name


def test_rows_of_no_scene_are_kept_after_every_scene(shaped):
    _, root, out, _ = shaped("cut_tail")  # keeps the sweeps whose sample is absent
    samples = {s["token"] for s in load(root / VERSION, "sample")}
    orphans = {d["token"] for d in load(root / VERSION, "sample_data") if d["sample_token"] not in samples}
    assert orphans  # the shape reaches the case
    frames = read(out, "frames")
    tail = frames.tail(len(orphans))
    assert set(tail["token"]) == orphans and tail["scene_name"].is_null().all()
    assert frames.head(frames.height - len(orphans))["scene_name"].is_not_null().all()


@pytest.mark.parametrize("name", ["cut_tail", "first_annotations_absent", "one_keyframe"])
def test_velocity_is_null_where_a_neighbour_is_absent_and_computed_elsewhere(shaped, name):
    _, root, out, _ = shaped(name)
    annotations = {a["token"]: a for a in load(root / VERSION, "sample_annotation")}
    rows = read(out, "annotations").select("token", "prev", "next", "velocity")
    cut = [r for r in rows.iter_rows(named=True)
           if (r["prev"] and r["prev"] not in annotations) or (r["next"] and r["next"] not in annotations)]
    assert cut and all(r["velocity"] is None for r in cut)
    whole = [r for r in rows.iter_rows(named=True) if r not in cut]
    assert all(r["velocity"] is not None for r in whole)


def test_a_source_field_named_like_a_joined_column_does_not_shadow_it(shaped, tmp_path):
    _, root, _, _ = shaped("category_name_field")
    convert(root, VERSION, tmp_path / "out")
    names = {c["token"]: c["name"] for c in load(root / VERSION, "category")}
    category_of = {i["token"]: names[i["category_token"]] for i in load(root / VERSION, "instance")}
    rows = read(tmp_path / "out", "annotations").select("instance_token", pl.col("category_name").cast(pl.String))
    assert rows["category_name"].to_list() == [category_of[i] for i in rows["instance_token"]]
    assert read(tmp_path / "out", "tables/sample_annotation")["category_name"][0].startswith('"')  # kept as JSON text


def test_worded_visibility_tokens_take_their_levels_from_the_table(shaped):
    _, root, out, _ = shaped("worded_visibility")
    rank = {"v0-40": 1, "v40-60": 2, "v60-80": 3, "v80-100": 4}
    levels = {v["token"]: v["level"] for v in load(root / VERSION, "visibility")}
    assert set(levels) == {"none", "partial", "most", "full"}
    rows = read(out, "annotations").select("visibility_token", "visibility_level", "visibility_name").unique()
    assert rows.height > 1
    for token, level, name in rows.iter_rows():
        assert name == levels[token] and level == rank[levels[token]]


def test_tables_2d_are_kept_and_their_dangling_references_reported(shaped):
    _, root, out, manifest = shaped("tables_2d")
    kinds = {f["path"]: f["kind"] for f in manifest["files"]}
    assert kinds[f"{VERSION}/object_ann.json"] == kinds[f"{VERSION}/surface_ann.json"] == "table_inferred"
    assert read(out, "tables/object_ann").height == len(load(root / VERSION, "object_ann"))
    assert [(e["table"], e["field"], e["count"]) for e in manifest["dangling"]["references"]] == \
        [("object_ann", "sample_data_token", 1)]


def test_sensor_points_leave_out_the_frames_of_no_scene_and_count_them(tmp_path):
    from nuparquet.synth import synthesize

    shape = next(s for s in SHAPES if s.name == "cut_tail")
    pristine = synthesize(tmp_path / "pristine", scenes=1, samples_per_scene=3, with_lidar=True, seed=4, version=VERSION)
    root = make(pristine, tmp_path / "data", shape)
    manifest = convert(root, VERSION, tmp_path / "out", allow_dangling=True, sensors=("lidar",), sweeps=True, workers=1,
                       embed=("lidar",))
    samples = {s["token"] for s in load(root / VERSION, "sample")}
    lidar = {c["token"] for c in load(root / VERSION, "calibrated_sensor")
             if c["sensor_token"] in {s["token"] for s in load(root / VERSION, "sensor") if s["modality"] == "lidar"}}
    frames = [d for d in load(root / VERSION, "sample_data") if d["calibrated_sensor_token"] in lidar]
    orphans = [d for d in frames if d["sample_token"] not in samples]
    assert orphans
    entry = manifest["datasets"]["lidar_points"]
    assert entry["no_scene_frames"] == len(orphans) and entry["frames"] == len(frames) - len(orphans)
    converted = set(read(tmp_path / "out", "lidar_points")["sample_data_token"].cast(pl.String))
    assert converted == {d["token"] for d in frames} - {d["token"] for d in orphans}
    assert any(w.startswith(f"lidar_points: {len(orphans)} frame(s) of no scene") for w in manifest["warnings"])
    embedded = manifest["datasets"]["sensor_files/lidar"]  # --embed leaves them out alike, and counts them
    assert embedded["no_scene_frames"] == len(orphans) and embedded["frames"] == len(frames) - len(orphans)
