"""Structured fuzz of the JSON tables: fixed-seed single mutations of a small synthetic dataroot's tables (a
deleted field, another JSON type, null, huge/negative/NaN numbers, unicode and control characters, long strings,
duplicate keys, a BOM, trailing garbage, deep nesting, an empty file, `{}` or `null` as a table). Every case must
end as an exact round trip (convert, then export-json gives the same records, types and key order) or a clean
refusal (exit 1 naming the file, nothing under OUT) — never a traceback and never a silent change."""

from __future__ import annotations

import json
import math
import random
import shutil
from pathlib import Path

import pytest

from conftest import EXTRACT_VERSION, SYNTH_VERSION
from nuparquet.cli.main import main

V = SYNTH_VERSION
CASES = 120
EXTRACT_CASES = 150
TABLES = ("attribute", "calibrated_sensor", "category", "ego_pose", "instance", "log", "map", "sample",
          "sample_annotation", "sample_data", "scene", "sensor", "visibility")


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("fuzz-pristine") / "data"
    synthesize(root, scenes=1, samples_per_scene=3, seed=11, version=V, with_can_bus=False)
    return root


def _value_mutations(rng: random.Random, value):
    return rng.choice([
        None, "", "x" * 100_000, "héllo\u2028\x07\x1b[31mred", 2**70, -(2**70), -1, 0, 1.5, math.nan, math.inf,
        True, [], {}, [1, "a"], {"k": [1, 2]}, str(value), [value], -1e308,
    ])


def _mutate(rng: random.Random, root: Path, version: str) -> str:
    """Apply one mutation; returns a description (the test id of the case)."""
    table = rng.choice(TABLES)
    path = root / version / f"{table}.json"
    records = json.loads(path.read_text())
    kind = rng.choice(["field", "field", "field", "delete", "text"])
    if kind == "text":
        text = path.read_text()
        op = rng.choice(["bom", "garbage", "nested", "empty", "object", "null", "duplicate", "truncate"])
        if op == "bom":
            text = "\ufeff" + text
        elif op == "garbage":
            text = text + "\n}garbage"
        elif op == "nested":
            text = text[:-2] + ', ' + "[" * 600 + "]" * 600 + "\n]" if len(records) else "[" + "[" * 600 + "]" * 600 + "]"
        elif op == "empty":
            text = ""
        elif op == "object":
            text = "{}"
        elif op == "null":
            text = "null"
        elif op == "duplicate" and records:  # a repeated key in one record (Python's json keeps the last value)
            key = rng.choice(list(records[0]))
            text = text.replace("{", "{" + json.dumps(key) + ': "dup", ', 1)
        elif op == "truncate":
            text = text[: len(text) // 2]
        path.write_text(text)
        return f"{table}:{op}"
    if not records:
        return f"{table}:empty-table"
    index = rng.randrange(len(records))
    field = rng.choice(list(records[index]))
    lists = [k for k, v in records[index].items() if isinstance(v, list) and v]
    if kind == "field" and lists and rng.random() < 0.5:  # one element of a list: a number that cannot be kept or used
        field = rng.choice(lists)
        element = rng.randrange(len(records[index][field]))
        records[index][field][element] = rng.choice([math.nan, math.inf, -1e308, 2**70, -1, 0, "1", None])
        path.write_text(json.dumps(records))
        return f"{table}[{index}].{field}[{element}]:element"
    if kind == "delete":
        del records[index][field]
    else:
        records[index][field] = _value_mutations(rng, records[index][field])
    path.write_text(json.dumps(records))
    return f"{table}[{index}].{field}:{kind}"


def run_case(pristine: Path, version: str, tmp_path: Path, capsys, seed: int) -> None:
    root = tmp_path / "data"
    shutil.copytree(pristine / version, root / version)
    what = _mutate(random.Random(seed), root, version)
    out = tmp_path / "out"
    code = main(["convert", str(root), "--version", version, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert "Traceback" not in err, what
    if code == 0:
        assert main(["export-json", str(out), "--out", str(tmp_path / "back"), "--quiet"]) == 0, what
        for table in TABLES:
            original = json.loads((root / version / f"{table}.json").read_text())
            again = json.loads((tmp_path / "back" / version / f"{table}.json").read_text())
            # the JSON text of both, re-serialised: values, JSON types (1 vs 1.0, true vs 1), key order and NaN exact
            assert json.dumps(original) == json.dumps(again), f"{what}: {table} changed"
    else:
        assert code == 1, f"{what}: exit {code}: {err[:300]}"
        # the mutated file, or the one whose references it broke (a changed token dangles elsewhere)
        assert any(f"{t}.json" in err for t in TABLES), f"{what}: the message names no file: {err[:300]}"
        assert not out.exists() and not list(tmp_path.glob(".out*")), what


@pytest.mark.parametrize("seed", range(CASES))
def test_synthetic_mutations_round_trip_exactly_or_are_refused_cleanly(pristine, tmp_path, capsys, seed):
    run_case(pristine, V, tmp_path, capsys, seed)


@pytest.mark.parametrize("seed", range(1000, 1000 + EXTRACT_CASES))
def test_real_extract_mutations_round_trip_exactly_or_are_refused_cleanly(extract_root, tmp_path, capsys, monkeypatch,
                                                                         seed):
    """The real extract's tables (5,049 annotations, 6,285 sample_data): only tables/ is built here (the derived
    datasets run in the synthetic cases above), so 150 cases stay near a minute."""
    import nuparquet.conversion.pipeline as convert_module

    monkeypatch.setattr(convert_module, "BUILDERS", ())
    run_case(extract_root, EXTRACT_VERSION, tmp_path, capsys, seed)
