"""Bad CAN bus files stop the conversion with exit 1 and a problem naming the file and the message; unusual but
valid files convert exactly; a dataroot without can_bus/ converts as before and says why nothing was built."""

from __future__ import annotations

import errno
import json
import os
import shutil
from pathlib import Path

import polars as pl
import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main
from nuparquet.conversion import convert
from nuparquet.export.json_files import export_json

V = SYNTH_VERSION
SCENE = "scene-0001"


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("can-pristine") / "data"
    synthesize(root, scenes=1, samples_per_scene=4, seed=5, version=V)
    return root


@pytest.fixture
def root(pristine, tmp_path) -> Path:
    copy = tmp_path / "data"
    shutil.copytree(pristine, copy)
    return copy


def _path(root: Path, message: str) -> Path:
    return root / "can_bus" / f"{SCENE}_{message}.json"


def _edit(root: Path, message: str, change) -> None:
    path = _path(root, message)
    records = json.loads(path.read_text())
    path.write_text(json.dumps(change(records)))


def _set(records, index, key, value):
    records[index][key] = value
    return records


def _drop(records, index, key):
    del records[index][key]
    return records


@pytest.mark.parametrize("message, change, expected", [
    ("pose", lambda r: {"messages": r}, "must be a JSON array of messages, not a dict"),
    ("pose", lambda r: _drop(r, 3, "utime"), "[3]: message has no utime"),
    ("pose", lambda r: _set(r, 5, "utime", r[4]["utime"]), "[5]: utime"),
    ("steeranglefeedback", lambda r: _set(r, 7, "utime", float(r[7]["utime"])), "[7]: utime must be an integer"),
    ("steeranglefeedback", lambda r: _set(r, 2, "value", "straight"), "[2]: message field 'value' is a str"),
    ("vehicle_monitor", lambda r: _drop(r, 1, "brake"), "[1]: message lacks brake"),
    ("ms_imu", lambda r: r[:3] + [7] + r[4:], "[3]: message is a int, not an object"),
    ("meta", lambda r: [r], "must be a JSON object of one object per message type"),
    ("route", lambda r: _set_point(r, 4, [1.0]), "[4]: point is not [x, y]"),
    ("route", lambda r: _set_point(r, 2, [2**53 + 1, r[2][1]]),
     "[2]: point coordinate is an integer beyond 2**53 (would not convert exactly)"),
    # a field of the second message type's object of another type: the record index is counted within the file
    ("meta", lambda r: {k: ({**v, "message_count": "many"} if i == 1 else v) for i, (k, v) in enumerate(r.items())},
     "[1]: message type field 'message_count' is a str where the others hold int values"),
])
def test_bad_files_are_problems_naming_file_and_message(root, tmp_path, capsys, message, change, expected):
    _edit(root, message, change)
    out = tmp_path / "out"
    assert main(["convert", str(root), "--version", V, "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert f"can_bus/{SCENE}_{message}.json" in err and expected in err, err
    assert not out.exists() and not list(tmp_path.glob(".out*"))


@pytest.mark.parametrize("extra, dtype", [({"kind": "pose"}, "String"), ("estimated", "String"), (1.5, "Float64")])
def test_pose_fields_the_can_bus_vector_cannot_take_are_refused_naming_file_and_field(root, tmp_path, capsys, extra,
                                                                                      dtype):
    """BEVFormer's loop `extend`s its vector with every pose field after pos and orientation: a number fails there
    (not iterable) and text or an object would put characters or keys into it. Such a field stops the conversion
    with a message naming the file and the field, not a traceback from deep in polars or numpy."""
    _edit(root, "pose", lambda records: [{**r, "extra": extra} for r in records])
    out = tmp_path / "out"
    assert main(["convert", str(root), "--version", V, "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert (f"can_bus/{SCENE}_pose.json: pose message field 'extra' holds {dtype} values, not lists of numbers"
            in err), err
    assert "Traceback" not in err and not out.exists() and not list(tmp_path.glob(".out*"))


def _set_point(records, index, value):
    records[index] = value
    return records


def test_invalid_json_is_a_problem(root, tmp_path, capsys):
    _path(root, "pose").write_text('[{"utime": 1,}]')
    assert main(["convert", str(root), "--version", V, "--out", str(tmp_path / "out"), "--quiet"]) == 1
    assert f"can_bus/{SCENE}_pose.json: not valid JSON" in capsys.readouterr().err


def test_integers_in_float_fields_and_other_key_orders_come_back_exactly(root, tmp_path):
    def unusual(records):
        records[0]["value"] = 0  # an int among floats
        records[1] = {"value": records[1]["value"], "utime": records[1]["utime"]}  # another key order
        return records

    _edit(root, "steeranglefeedback", unusual)
    _edit(root, "pose", lambda r: _set(r, 2, "pos", [1, r[2]["pos"][1], 0]))
    convert(root, V, tmp_path / "out")
    export_json(tmp_path / "out", tmp_path / "back")
    for message in ("steeranglefeedback", "pose"):
        original = json.loads(_path(root, message).read_text())
        again = json.loads(_path(tmp_path / "back", message).read_text())
        assert again == original
        assert [list(r) for r in again] == [list(r) for r in original]
        assert [[type(v) for v in r.values()] for r in again] == [[type(v) for v in r.values()] for r in original]
    again = json.loads(_path(tmp_path / "back", "pose").read_text())
    assert type(again[2]["pos"][0]) is int and type(again[2]["pos"][2]) is int and type(again[3]["pos"][0]) is float


def test_files_of_scenes_outside_the_version_are_ignored(root, tmp_path):
    shutil.copy(_path(root, "pose"), root / "can_bus" / "scene-9999_pose.json")
    manifest = convert(root, V, tmp_path / "out")
    assert "scene-9999" not in set(pl.read_parquet(tmp_path / "out" / "can_bus" / "pose")["scene_name"])
    assert not any("scene-9999" in f["path"] for f in manifest["files"])


def test_a_dataroot_without_can_bus_converts_as_before(root, tmp_path):
    shutil.rmtree(root / "can_bus")
    manifest = convert(root, V, tmp_path / "out")
    assert manifest["skipped"] == {"can_bus": "no can_bus/ folder in the dataroot",
                                   "sample_can_bus": "needs can_bus, not built",
                                   "lidar_points": "not requested (--sensors lidar)",
                                   "radar_points": "not requested (--sensors radar)",
                                   **{f"sensor_files/{m}": f"not requested (--embed {m})"
                                      for m in ("camera", "lidar", "radar")}}
    assert not any(name.startswith(("can_bus", "sample_can_bus")) for name in manifest["datasets"])
    assert not (tmp_path / "out" / "sample_can_bus").exists()


def test_message_and_route_files_that_are_empty_arrays_convert_typed_and_come_back(root, tmp_path):
    """Every file of a message type (and the route) holding `[]`: the datasets are empty but typed as when they hold
    messages (utime Int64, x and y Float64), no sample has that message, and export-json writes `[]` back."""
    for message in ("route", "steeranglefeedback"):
        _path(root, message).write_text("[]")
    convert(root, V, tmp_path / "out")
    route = pl.read_parquet(tmp_path / "out" / "can_bus" / "route")
    steering = pl.read_parquet(tmp_path / "out" / "can_bus" / "steeranglefeedback")
    assert route.height == 0 and route.schema["x"] == pl.Float64 and route.schema["y"] == pl.Float64
    assert steering.height == 0 and steering.schema["utime"] == pl.Int64
    aligned = pl.read_parquet(tmp_path / "out" / "sample_can_bus")
    assert aligned.height == 4 and aligned["steeranglefeedback"].is_null().all()
    assert aligned["steeranglefeedback_age_us"].is_null().all() and aligned["pose"].is_not_null().any()
    export_json(tmp_path / "out", tmp_path / "back")
    for message in ("route", "steeranglefeedback"):
        assert json.loads(_path(tmp_path / "back", message).read_text()) == []


def test_integer_route_coordinates_come_back_as_integers(root, tmp_path):
    """A route point written with integers (600 rather than 600.0, on either axis) is exported as it was read; the
    manifest's entry for the route file names a point's fields as the columns of can_bus/route (x, y) and, by point,
    the integer ones."""
    def integers(points):
        points[0] = [int(points[0][0]), points[0][1]]  # x an integer
        points[1] = [points[1][0], int(points[1][1])]  # y an integer
        points[2] = [int(points[2][0]), int(points[2][1])]
        return points

    _edit(root, "route", integers)
    manifest = convert(root, V, tmp_path / "out")
    entry, = (f for f in manifest["files"] if f["path"] == f"can_bus/{SCENE}_route.json")
    assert entry["kind"] == "can_bus_route" and entry["dataset"] == "can_bus/route"
    route_columns = pl.read_parquet(tmp_path / "out" / "can_bus" / "route").columns
    assert entry["keys"] == ["x", "y"] and set(entry["keys"]) <= set(route_columns)
    assert entry["int_values"] == {"x": [0, 2], "y": [1, 2]}
    export_json(tmp_path / "out", tmp_path / "back")
    original = json.loads(_path(root, "route").read_text())
    again = json.loads(_path(tmp_path / "back", "route").read_text())
    assert again == original
    assert [[type(c) for c in p] for p in again] == [[type(c) for c in p] for p in original]
    assert [[type(c) for c in p] for p in again[:3]] == [[int, float], [float, int], [int, int]]


def test_a_file_that_cannot_be_read_is_a_problem_naming_it_even_when_the_next_scenes_file_is_fine(tmp_path):
    """Two scenes' pose files: the first is a folder (read_text raises IsADirectoryError), the second is valid. The
    problem names the first file and why it cannot be read; the type is not read from the good file alone."""
    from nuparquet.sources.can_bus import discover, read_messages

    (tmp_path / "can_bus" / "scene-0001_pose.json").mkdir(parents=True)
    (tmp_path / "can_bus" / "scene-0002_pose.json").write_text(json.dumps([{"utime": 1, "vel": [1.0, 0.0, 0.0]}]))
    found, others = discover(tmp_path, {"scene-0001", "scene-0002"})
    assert [f.name for f in found["pose"]] == ["can_bus/scene-0001_pose.json", "can_bus/scene-0002_pose.json"]
    read, problems = read_messages(tmp_path, found["pose"])
    assert read is None
    assert [str(p) for p in problems] == [f"can_bus/scene-0001_pose.json: cannot be read ({os.strerror(errno.EISDIR)})"]
