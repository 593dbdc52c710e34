"""Conversion of whole datasets: row counts, exact round trip, schemas, determinism, CLI behaviour."""

from __future__ import annotations

import json
from pathlib import Path

import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from conftest import EXTRACT_VERSION, SYNTH_VERSION
from nuparquet.cli.main import main
from nuparquet.export.json_files import export_json
from nuparquet.schemas import core_tables, schema_for, table_schemas


def _json_tables(root: Path, version: str) -> dict[str, list[dict]]:
    return {name: json.loads((root / version / f"{name}.json").read_text()) for name in core_tables()}


def _assert_round_trip(source_root: Path, version: str, out: Path, tmp_path: Path) -> None:
    exported = tmp_path / "exported"
    export_json(out, exported)
    for name, records in _json_tables(source_root, version).items():
        again = json.loads((exported / version / f"{name}.json").read_text())  # DIR is a dataroot
        assert len(again) == len(records), name
        for original, copy in zip(records, again):
            assert list(copy) == list(original), f"{name}: key order"  # same keys, same order
            assert copy == original, f"{name} token={original.get('token')}"
            for key, value in original.items():  # 1 == 1.0 in Python: also check the JSON types
                assert type(copy[key]) is type(value), f"{name}.{key}"


def _assert_row_counts(source_root: Path, version: str, out: Path) -> None:
    manifest = json.loads((out / "manifest.json").read_text())
    for name, records in _json_tables(source_root, version).items():
        assert manifest["datasets"][f"tables/{name}"]["rows"] == len(records)
        assert pq.read_metadata(next((out / "tables" / name).glob("*.parquet"))).num_rows == len(records)
    assert manifest["datasets"]["frames"]["rows"] == len(_json_tables(source_root, version)["sample_data"])
    assert manifest["datasets"]["annotations"]["rows"] == len(_json_tables(source_root, version)["sample_annotation"])


def _assert_schemas(out: Path) -> None:
    for name, schema in table_schemas().items():
        files = list((out / "tables" / name).glob("*.parquet"))
        if files:
            written = pq.read_schema(files[0])
            assert written.remove_metadata().equals(schema.arrow_schema()), name
    manifest = json.loads((out / "manifest.json").read_text())
    for name in manifest["datasets"]:
        schema = schema_for(name)
        if schema is None or name.startswith("tables/") or name == "radar_points":
            continue  # inferred (CAN bus messages); tables above; radar: the PCD header's fields, test_points.py
        written = pq.read_schema(next((out / name).glob("*.parquet")))
        if schema.extra:  # the declared columns with their types, the input's own columns beside them
            declared = [f for f in written if f.name in schema.names]
            assert pa.schema(declared).equals(schema.arrow_schema().remove_metadata()), name
        else:
            assert written.remove_metadata().equals(schema.arrow_schema()), name
    assert {"frames", "annotations", "scenes", "instances"} <= set(manifest["datasets"])


def test_real_extract_row_counts_match_the_json(extract_root, extract_out):
    _assert_row_counts(extract_root, EXTRACT_VERSION, extract_out)


def test_real_extract_round_trips_exactly(extract_root, extract_out, tmp_path):
    _assert_round_trip(extract_root, EXTRACT_VERSION, extract_out, tmp_path)


def test_real_extract_written_schemas_equal_the_schema_files(extract_out):
    _assert_schemas(extract_out)


def test_synthetic_row_counts_round_trip_and_schemas(synth_root, synth_out, tmp_path):
    _assert_row_counts(synth_root, SYNTH_VERSION, synth_out)
    _assert_round_trip(synth_root, SYNTH_VERSION, synth_out, tmp_path)
    _assert_schemas(synth_out)


def test_synthetic_dataset_validates_clean(synth_root, capsys):
    assert main(["validate", str(synth_root), "--version", SYNTH_VERSION]) == 0
    assert "no problems" in capsys.readouterr().out


def test_conversion_is_deterministic(synth_root, synth_out, tmp_path):
    again = tmp_path / "again"
    assert main(["convert", str(synth_root), "--version", SYNTH_VERSION, "--out", str(again), "--quiet"]) == 0
    for dataset in ["frames", "annotations", "scenes", "instances", "tables/sample_data"]:
        first = pl.read_parquet(synth_out / dataset / "*.parquet")
        second = pl.read_parquet(again / dataset / "*.parquet")
        assert first.equals(second, null_equal=True), dataset


def test_manifest_records_versions_counts_fingerprints_and_input_files(synth_root, synth_out):
    manifest = json.loads((synth_out / "manifest.json").read_text())
    assert manifest["format"] == "nuparquet" and manifest["format_version"] == 2
    assert manifest["source"]["version"] == SYNTH_VERSION
    assert Path(manifest["source"]["dataroot"]) == synth_root.resolve()
    sizes = {name: info["bytes"] for name, info in manifest["source"]["files"].items()}
    assert sizes["sample_data.json"] == (synth_root / SYNTH_VERSION / "sample_data.json").stat().st_size
    assert {"frames", "annotations", "scenes", "instances", "tables/sample"} <= set(manifest["datasets"])
    assert all(len(d["schema_fingerprint"]) == 16 for d in manifest["datasets"].values())


def test_export_json_cli_refuses_existing_directory(synth_out, tmp_path):
    target = tmp_path / "exists"
    target.mkdir()
    assert main(["export-json", str(synth_out), "--out", str(target)]) == 2


def _rewrite(path: Path, change, indent: int | None) -> None:
    """Edit a JSON file, writing it back in its own layout (checked: the unedited text re-dumps to the same bytes)."""
    text = path.read_text()
    data = json.loads(text)
    assert json.dumps(data, indent=indent) == text, path.name
    change(data)
    path.write_text(json.dumps(data, indent=indent))


def test_every_input_file_comes_back_byte_for_byte_whatever_its_shape(tmp_path):
    """One small dataroot holding what each writer of export-json has to give back and the generator's own files
    lack: integers where a CAN bus message or meta field otherwise holds floats, a CAN bus field of no one type
    (JSON text), a record in another key order, a field no schema knows (JSON text) that is null in one record and
    absent from another, integers in a table's float list and a float in its integer field, an extra table no
    schema describes (inferred) on one line with a record in another key order, beside the map expansion file. Every JSON file of the dataroot comes back
    byte for byte, and parsed, with the same JSON types (1 is not 1.0)."""
    from nuparquet.conversion import convert
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path / "data", scenes=1, samples_per_scene=4, seed=5, version=SYNTH_VERSION)
    can, tables = root / "can_bus", root / SYNTH_VERSION

    def steering(records):
        records[0]["value"] = 0  # an int among floats
        records[1] = {"value": records[1]["value"], "utime": records[1]["utime"]}  # another key order
        for i, record in enumerate(records):  # objects in a message field: kept as JSON text
            record["note"] = {"rain": i % 2 == 1, "lux": [i, 0.5]} if i % 3 else {"fog": None}

    def pose(records):
        records[2]["pos"] = [1, records[2]["pos"][1], 0]  # ints inside a float list

    def meta(messages):
        messages["POSE"]["timespan"] = 20  # an int where the other messages' timespans are floats
        assert type(messages["MS_IMU"]["timespan"]) is float

    def weather(records):  # a field no schema knows: objects, null in one record, absent from the last
        for i, record in enumerate(records[:-1]):
            record["weather"] = None if i == 2 else {"rain": i % 2 == 1, "lux": [i, 0.5]}

    _rewrite(can / "scene-0001_steeranglefeedback.json", steering, None)
    _rewrite(can / "scene-0001_pose.json", pose, None)
    _rewrite(can / "scene-0001_meta.json", meta, 0)
    def ego_pose(records):  # a schema table's JSON types the columns cannot hold
        records[0]["translation"] = [1, records[0]["translation"][1], 0]  # ints in a float list
        records[1]["timestamp"] = float(records[1]["timestamp"])  # a float in an integer field

    _rewrite(tables / "sample.json", weather, 0)
    _rewrite(tables / "ego_pose.json", ego_pose, 0)
    frames = json.loads((tables / "sample_data.json").read_text())
    objects = [{"token": f"{i:032x}", "sample_data_token": frames[i]["token"], "bbox": [10 + i, 20, 30.5, 40],
                "attribute_tokens": []} for i in range(3)]
    objects[1] = dict(reversed(list(objects[1].items())))
    (tables / "object_ann.json").write_text(json.dumps(objects))  # on one line: not the indent=0 of the tables

    manifest = convert(root, SYNTH_VERSION, tmp_path / "out")
    kinds = {f["path"]: f["kind"] for f in manifest["files"]}
    assert kinds[f"{SYNTH_VERSION}/object_ann.json"] == "table_inferred"
    assert kinds["maps/expansion/boston-seaport.json"] == "map_expansion"
    assert kinds["can_bus/scene-0001_meta.json"] == "can_bus_meta"
    export_json(tmp_path / "out", tmp_path / "back")
    originals = sorted(p.relative_to(root) for p in root.rglob("*.json"))
    assert sorted(p.relative_to(tmp_path / "back") for p in (tmp_path / "back").rglob("*.json")) == originals
    for path in originals:
        source, again = (root / path).read_bytes(), (tmp_path / "back" / path).read_bytes()
        assert json.dumps(json.loads(again)) == json.dumps(json.loads(source)), path  # types and key order
        assert again == source, path


def _with_manifest(converted: Path, manifest: dict, where: Path) -> Path:
    """`converted` linked into `where`, but for its manifest: `manifest` instead."""
    where.mkdir()
    for child in converted.iterdir():
        if child.name != "manifest.json":
            (where / child.name).symlink_to(child, target_is_directory=child.is_dir())
    (where / "manifest.json").write_text(json.dumps(manifest))
    return where


def test_export_json_of_a_file_kind_it_cannot_write_refuses_naming_the_kind_and_the_kinds_it_knows(synth_out, tmp_path):
    """A manifest listing a file of a kind this nuparquet does not know (written by a newer one): refused before
    anything is written, naming the kind, every kind it can write back and the fix."""
    from nuparquet.errors import FormatError

    manifest = json.loads((synth_out / "manifest.json").read_text())
    manifest["files"].append({"path": "radar_tracks/scene-0001.json", "kind": "radar_tracks", "dataset": "tables/scene"})
    converted = _with_manifest(synth_out, manifest, tmp_path / "converted")
    with pytest.raises(FormatError, match=r"lists files of kind radar_tracks, which this nuparquet cannot write back "
                                          r"\(known: .*\); upgrade nuparquet$") as error:
        export_json(converted, tmp_path / "back")
    known = str(error.value).split("(known: ")[1].split(")")[0].split(", ")
    # the kinds the conversion writes (docs/CONTRACTS.md, conversion/pipeline.py and the CAN bus and map builders)
    assert sorted(known) == sorted(["table", "table_inferred", "can_bus_messages", "can_bus_meta", "can_bus_route",
                                    "map_expansion"])
    assert {f["kind"] for f in manifest["files"]} - {"radar_tracks"} <= set(known)
    assert not (tmp_path / "back").exists()


def test_export_json_into_the_converted_dataset_is_refused_naming_it(synth_out):
    from nuparquet.errors import UsageError

    for out, relation in ((synth_out, "is"), (synth_out / "json", "is inside")):
        with pytest.raises(UsageError) as refused:
            export_json(synth_out, out)
        assert str(refused.value) == f"{out} {relation} the converted dataset {synth_out}; write the output somewhere else"
    assert not (synth_out / "json").exists()


def test_export_json_of_a_manifest_without_its_file_list_writes_the_tables_under_the_version_folder(
        synth_root, synth_out, tmp_path):
    """A manifest that lists no files (written before it did): the tables come back at <version>/<table>.json, as
    the source's version folder holds them; one that names no source version either is refused by name, nothing
    written (its tables would otherwise land at the filesystem's root)."""
    from nuparquet.errors import FormatError

    manifest = json.loads((synth_out / "manifest.json").read_text())
    del manifest["files"]
    converted = _with_manifest(synth_out, manifest, tmp_path / "converted")
    written = export_json(converted, tmp_path / "back")
    expected = sorted(p.relative_to(synth_root) for p in (synth_root / SYNTH_VERSION).glob("*.json"))
    assert len(expected) > 10 and sorted(p.relative_to(tmp_path / "back") for p in written) == expected
    for path in expected:
        assert json.loads((tmp_path / "back" / path).read_text()) == json.loads((synth_root / path).read_text()), path
    del manifest["source"]
    (converted / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(FormatError, match=r"^manifest\.json lists neither the files converted nor the source version"):
        export_json(converted, tmp_path / "again")
    assert not (tmp_path / "again").exists()


@pytest.mark.parametrize("argv", [["convert", "/nonexistent/dataroot", "--version", "v1.0-mini", "--out", "/tmp/never"]])
def test_missing_dataroot_is_a_usage_error(argv, capsys):
    assert main(argv) == 2
    assert "not a directory" in capsys.readouterr().err
