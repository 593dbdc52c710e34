"""One huge string in a small table must not blow up the conversion's memory (a 40 MB string once took it past
18 GB; a 40 MB sensor.modality to 24 GB, a 40 MB log.location past two minutes and a polars panic): measured as the
peak RSS of a conversion in its own process, under the 8 GB address-space cap of `make test-capped`."""

from __future__ import annotations

import json
import resource
import shutil
import subprocess
import sys

import pytest

from conftest import SYNTH_VERSION

V = SYNTH_VERSION
LIMIT_MB = 1500  # the same conversion without the string peaks near 460 MB; with it, 0.7-1.0 GB measured
ADDRESS_SPACE = 8_000_000 * 1024  # `ulimit -v 8000000`


def _capped() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


# Strings that reach every row of a derived dataset (modality, location, visibility's words) and one that does not.
@pytest.mark.parametrize("table, field", [("scene", "description"), ("sensor", "modality"), ("log", "location"),
                                          ("visibility", "description"), ("category", "name")])
def test_a_40_mb_string_keeps_memory_bounded_and_round_trips(synth_root, tmp_path, table, field):
    root = tmp_path / "data"
    shutil.copytree(synth_root / V, root / V)
    path = root / V / f"{table}.json"
    records = json.loads(path.read_text())
    records[0][field] = "x" * 40_000_000
    path.write_text(json.dumps(records))
    script = ("import sys; from nuparquet.cli.main import main; "
              f"sys.exit(main(['convert', {str(root)!r}, '--version', {V!r}, '--out', {str(tmp_path / 'out')!r}, '--quiet']))")
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, preexec_fn=_capped,
                          timeout=300)
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    assert done.returncode == 0, done.stderr[-500:]
    assert before / 1024 < LIMIT_MB  # the measurement is this child's, not an earlier larger one
    assert peak_mb < LIMIT_MB, f"peak RSS {peak_mb:.0f} MB"
    from nuparquet.export.json_files import export_json

    export_json(tmp_path / "out", tmp_path / "back")
    again = json.loads((tmp_path / "back" / V / f"{table}.json").read_text())
    assert again[0][field] == records[0][field]


def test_a_string_over_the_documented_limit_is_refused_naming_file_record_and_field(synth_root, tmp_path, capsys):
    from nuparquet.cli.main import main
    from nuparquet.sources import table_scan

    root = tmp_path / "data"
    shutil.copytree(synth_root / V, root / V)
    path = root / V / "log.json"
    records = json.loads(path.read_text())
    records[1]["vehicle"] = "x" * (table_scan.MAX_STRING_BYTES + 1)
    path.write_text(json.dumps(records))
    assert main(["convert", str(root), "--version", V, "--out", str(tmp_path / "out"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert (f"log.json[1] token={records[1]['token']}: field 'vehicle' holds a string longer than 67,108,864 bytes "
            "(the longest a table may hold)") in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("table, field", [("scene", "name"), ("sensor", "channel"), ("attribute", "name"),
                                          ("sample", "scene_token"), ("sample_annotation", "attribute_tokens")])
def test_a_name_or_token_over_its_schema_limit_is_refused_naming_file_record_and_field(synth_root, tmp_path, capsys,
                                                                                      table, field):
    """Names that reach every row of a derived dataset and tokens have a documented limit (`max_bytes` in
    schemas/tables): one byte over it is refused, exactly at it is read."""
    from nuparquet.cli.main import main
    from nuparquet.schemas import table_schemas

    limit = table_schemas()[table].field(field).max_bytes
    assert limit == 4096
    root = tmp_path / "data"
    shutil.copytree(synth_root / V, root / V)
    path = root / V / f"{table}.json"
    records = json.loads(path.read_text())
    index = next(i for i, r in enumerate(records) if r[field])
    records[index][field] = ["é" * (limit // 2)] if isinstance(records[index][field], list) else "é" * (limit // 2)
    path.write_text(json.dumps(records))
    from nuparquet.sources.tables import read_table

    source, problems = read_table(path, table_schemas()[table])
    assert problems == []  # exactly at the limit: read (it may dangle later; that is the integrity check's)
    records[index][field] = ["x" * (limit + 1)] if isinstance(records[index][field], list) else "x" * (limit + 1)
    path.write_text(json.dumps(records))
    assert main(["convert", str(root), "--version", V, "--out", str(tmp_path / "out"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert (f"{table}.json[{index}] token={records[index]['token']}: field {field!r} holds a string of "
            f"{limit + 1:,} bytes, over its limit of {limit:,}: ") in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
