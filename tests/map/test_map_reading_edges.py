"""The map reader's checks and exact typing where its fast paths (whole lists checked as sets, nested fields compared
by repr) could let something through: every damage below must still be a problem naming the record, and nested
values that Arrow would change (an int among floats, another key order) must come back exactly."""

from __future__ import annotations

import json

import pytest

from conftest import SYNTH_VERSION, first_map
from nuparquet.cli.main import main
from nuparquet.conversion import convert
from nuparquet.export.json_files import export_json


def _with_hole(d):
    """Polygon 0 gets a hole naming an unknown node (the exterior stays valid)."""
    d["polygon"][0]["holes"] = [{"node_tokens": [d["node"][0]["token"], "e" * 32, d["node"][1]["token"]]}]


def _tokens_as_strings(d):
    """Every drivable area names its polygon by a bare (known) token instead of a list of them."""
    for record in d["drivable_area"]:
        record["polygon_tokens"] = record["polygon_tokens"][0]


@pytest.mark.parametrize("change, expected, token_of", [
    (_with_hole, "names node '" + "e" * 32 + "' (holes)", lambda d: d["polygon"][0]["token"]),
    (lambda d: d["line"][1].__setitem__("node_tokens", "not-a-list"), "line field node_tokens must be a list",
     lambda d: d["line"][1]["token"]),
    (lambda d: d["polygon"][2].__setitem__("holes", [["a", "b"]]), "polygon field holes must be a list",
     lambda d: d["polygon"][2]["token"]),
    (lambda d: d["drivable_area"][0]["polygon_tokens"].append("d" * 32),
     "drivable_area field polygon_tokens names polygon '" + "d" * 32 + "'", lambda d: d["drivable_area"][0]["token"]),
    (lambda d: d["lane_divider"][0].pop("line_token"), "lane_divider field line_token names line None",
     lambda d: d["lane_divider"][0]["token"]),
    (lambda d: d["walkway"].__setitem__(0, {"polygon_token": d["walkway"][0]["polygon_token"]}),
     "walkway must be a list of objects with a token", lambda d: None),
    (lambda d: d["node"][4].__setitem__("token", 7), "node must be a list of objects with a token", lambda d: None),
    # a known token in the wrong shape, or an item no token can be: a problem, not a KeyError or TypeError later
    (_tokens_as_strings, "drivable_area field polygon_tokens must be a list of polygon tokens, not '",
     lambda d: d["drivable_area"][0]["token"]),
    (lambda d: d["lane"][1].__setitem__("polygon_token", [d["lane"][1]["polygon_token"]]),
     "lane field polygon_token must be one polygon token, not ['", lambda d: d["lane"][1]["token"]),
    (lambda d: d["drivable_area"][0]["polygon_tokens"].append(["x"]),
     "drivable_area field polygon_tokens names polygon ['x']", lambda d: d["drivable_area"][0]["token"]),
    (lambda d: d["drivable_area"][0]["polygon_tokens"].append(None),
     "drivable_area field polygon_tokens names polygon None", lambda d: d["drivable_area"][0]["token"]),
])
def test_damage_the_fast_checks_must_still_find(small_map_root, tmp_path, capsys, change, expected, token_of):
    path = first_map(small_map_root)
    data = json.loads(path.read_text())
    change(data)
    token = token_of(data)
    path.write_text(json.dumps(data))
    out = tmp_path / "out"
    assert main(["convert", str(small_map_root), "--version", SYNTH_VERSION, "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert f"maps/expansion/{path.name}" in err and expected in err, err
    if token:
        assert f"token={token}" in err
    assert not out.exists()


def test_nested_values_arrow_would_change_come_back_exactly(small_map_root, tmp_path):
    path = first_map(small_map_root)
    data = json.loads(path.read_text())
    lanes = [lane for lane in data["lane"] if lane["left_lane_divider_segments"]]
    segment = lanes[0]["left_lane_divider_segments"][0]
    lanes[0]["left_lane_divider_segments"][0] = dict(reversed(list(segment.items())))  # another key order inside
    data["traffic_light"][0]["pose"]["tx"] = 3  # an int where the other lights have floats
    path.write_text(json.dumps(data))
    convert(small_map_root, SYNTH_VERSION, tmp_path / "out")
    export_json(tmp_path / "out", tmp_path / "back")
    again = json.loads((tmp_path / "back" / "maps" / "expansion" / path.name).read_text())
    assert json.dumps(again) == json.dumps(data)
