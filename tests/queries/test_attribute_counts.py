"""`attribute_counts` on annotations without a usable attribute: none at all, or only a token that names no attribute
record (a trimmed extract converted with `--allow-dangling`), counted by hand from the JSON: per attribute name,
the annotations whose `attribute_tokens` name its record, as the devkit's `list_attributes` counts (which raises a
KeyError on the unknown token: here it counts nowhere, as the docstring says of an annotation without attributes).

The first case alone never reached the null filter: polars' `explode` drops the row of an empty list."""

from __future__ import annotations

import json
from collections import Counter

import pytest

import nuparquet
from conftest import SYNTH_VERSION
from nuparquet import queries

MISSING = "no-such-attribute-token"


@pytest.fixture(scope="module")
def edited(tmp_path_factory):
    """A 1-scene synthetic dataroot whose first annotations lose their attributes: the first has none, the second only
    a token of no attribute record, the third one real attribute and that token; converted with --allow-dangling."""
    from nuparquet.conversion import convert
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path_factory.mktemp("attr") / "data", scenes=1, samples_per_scene=3, seed=5,
                      version=SYNTH_VERSION, with_can_bus=False)
    path = root / SYNTH_VERSION / "sample_annotation.json"
    records = json.loads(path.read_text())
    assert len(records) >= 3 and all(r["attribute_tokens"] for r in records[:3])
    records[0]["attribute_tokens"] = []
    records[1]["attribute_tokens"] = [MISSING]
    records[2]["attribute_tokens"] = [records[2]["attribute_tokens"][0], MISSING]
    path.write_text(json.dumps(records, indent=0))
    out = tmp_path_factory.mktemp("attr-out") / "out"
    convert(root, SYNTH_VERSION, out, allow_dangling=True)
    tables = {name: json.loads((root / SYNTH_VERSION / f"{name}.json").read_text())
              for name in ("attribute", "category", "instance", "sample_annotation")}
    return tables, nuparquet.open(out)


def test_annotations_without_an_attribute_or_with_an_unknown_one_count_nowhere(edited):
    tables, ds = edited
    name = {a["token"]: a["name"] for a in tables["attribute"]}
    category = {c["token"]: c["name"] for c in tables["category"]}
    category_of = {i["token"]: category[i["category_token"]] for i in tables["instance"]}
    expected = Counter(name[t] for a in tables["sample_annotation"] for t in a["attribute_tokens"] if t in name)
    ours = queries.attribute_counts(ds).collect()
    assert None not in ours["attribute_name"].to_list()
    assert dict(ours.rows()) == expected and ours["attribute_name"].to_list() == sorted(expected)
    by_category = Counter((category_of[a["instance_token"]], name[t]) for a in tables["sample_annotation"]
                          for t in a["attribute_tokens"] if t in name)
    ours = queries.attribute_counts(ds, by_category=True).collect()
    assert {(c, n): k for c, n, k in ours.rows()} == by_category
