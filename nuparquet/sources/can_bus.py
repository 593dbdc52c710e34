"""The nuScenes CAN bus expansion: `DATAROOT/can_bus/scene-XXXX_<message>.json`.

One file per scene and message type: a JSON array of messages with a strictly increasing `utime` (µs) for
the CAN messages (ms_imu, pose, steeranglefeedback, vehicle_monitor, zoesensors, zoe_veh_info, and any other
name found), an object per message type for `<scene>_meta.json` (message_count, message_freq, timespan,
var_stats), and a list of [x, y] points for `<scene>_route.json`. Read as the devkit reads them
(`NuScenesCanBus.get_messages`: `json.load` of the file) and typed by `json_records`; only scenes of the
converted version are read (the expansion ships every scene of nuScenes in one folder).
"""

from __future__ import annotations

import json
import re
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa

from nuparquet.problems import Problem
from nuparquet.sources.json_records import Columns, Located, to_columns

FOLDER = "can_bus"
FILE_NAME = re.compile(r"^(?P<scene>scene-\d+)_(?P<message>[a-z0-9_]+)\.json$", re.IGNORECASE)
META, ROUTE = "meta", "route"  # derived files, not CAN messages


@dataclass(frozen=True)
class CanBusFile:
    scene: str
    message: str
    path: Path  # relative to the dataroot

    @property
    def name(self) -> str:
        return self.path.as_posix()


@dataclass
class Read:
    """What one kind of file became: typed columns (with `scene_name` first) and per-file facts for export."""

    table: pa.Table
    columns: Columns
    files: list[CanBusFile]
    starts: list[int]  # first row of each file in `table`


def discover(dataroot: Path, scenes: set[str]) -> tuple[dict[str, list[CanBusFile]], int]:
    """{message: files of the converted scenes, in scene order} and the number of files of other scenes."""
    found: dict[str, list[CanBusFile]] = defaultdict(list)
    others = 0
    for path in sorted((dataroot / FOLDER).glob("*.json")):
        match = FILE_NAME.match(path.name)
        if match is None:
            continue
        if match["scene"] not in scenes:
            others += 1
            continue
        found[match["message"]].append(CanBusFile(match["scene"], match["message"], path.relative_to(dataroot)))
    return dict(sorted(found.items())), others


def _load(dataroot: Path, file: CanBusFile) -> tuple[object, list[Problem]]:
    try:
        return json.loads((dataroot / file.path).read_text()), []
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        return None, [Problem(file.name, f"not valid JSON ({exc})")]
    except OSError as exc:
        return None, [Problem(file.name, f"cannot be read ({exc.strerror or exc})")]


def read_messages(dataroot: Path, files: list[CanBusFile]) -> tuple[Read | None, list[Problem]]:
    """Every file of one CAN message type: a list of objects, each with an integer `utime` that increases."""
    records: list[dict] = []
    scene_names: list[str] = []
    starts: list[int] = []
    problems: list[Problem] = []
    for file in files:
        messages, file_problems = _load(dataroot, file)
        if not file_problems and not isinstance(messages, list):
            file_problems = [Problem(file.name, f"must be a JSON array of messages, not a {type(messages).__name__}")]
        if not file_problems:
            file_problems = _check_messages(file, messages)
        problems += file_problems
        if file_problems:
            continue
        starts.append(len(records))
        records += messages
        scene_names += [file.scene] * len(messages)
    if problems:
        return None, problems
    columns, column_problems = to_columns(records, Located([f.name for f in files], starts), "message")
    if column_problems:
        return None, column_problems
    table = columns.table
    if not records:
        table = pa.table({"scene_name": pa.array([], pa.string()), "utime": pa.array([], pa.int64())})
    else:  # scene_name, utime, then the fields in the files' order
        table = table.select(["utime"] + [k for k in columns.keys if k != "utime"])
        table = table.add_column(0, "scene_name", pa.array(scene_names, pa.string()))
    return Read(table, columns, list(files), starts), []


def _check_messages(file: CanBusFile, messages: list) -> list[Problem]:
    problems = []
    previous = None
    for i, message in enumerate(messages):
        if not isinstance(message, dict):
            problems.append(Problem(file.name, f"message is a {type(message).__name__}, not an object", i))
        elif "utime" not in message:
            problems.append(Problem(file.name, "message has no utime", i))
        elif type(message["utime"]) is not int:
            problems.append(Problem(file.name, f"utime must be an integer (µs), not {json.dumps(message['utime'])[:40]}", i))
        else:
            if previous is not None and message["utime"] <= previous:
                problems.append(Problem(file.name, f"utime {message['utime']} does not increase (previous message: "
                                                   f"{previous})", i))
            previous = message["utime"]
        if len(problems) >= 20:
            break
    return problems


def read_meta(dataroot: Path, files: list[CanBusFile]) -> tuple[Read | None, list[Problem]]:
    """`<scene>_meta.json`: an object {MESSAGE_NAME: {message_count, message_freq, timespan, var_stats}}; one row
    per scene and message, in file order, `message` as spelled in the file."""
    records, scene_names, names, starts, problems = [], [], [], [], []
    for file in files:
        meta, file_problems = _load(dataroot, file)
        if not file_problems and not (isinstance(meta, dict) and all(isinstance(v, dict) for v in meta.values())):
            file_problems = [Problem(file.name, "must be a JSON object of one object per message type")]
        problems += file_problems
        if file_problems:
            continue
        starts.append(len(records))
        records += list(meta.values())
        names += list(meta)
        scene_names += [file.scene] * len(meta)
    if problems:
        return None, problems
    columns, column_problems = to_columns(records, Located([f.name for f in files], starts), "message type")
    if column_problems:
        return None, column_problems
    table = columns.table.add_column(0, "message", pa.array(names, pa.string())) \
        .add_column(0, "scene_name", pa.array(scene_names, pa.string()))
    return Read(table, columns, list(files), starts), []


def read_route(dataroot: Path, files: list[CanBusFile]) -> tuple[Read | None, list[Problem]]:
    """`<scene>_route.json`: a list of [x, y] points (map metres); one row per point, `point_index` from 0."""
    records, scene_names, starts, problems = [], [], [], []
    for file in files:
        route, file_problems = _load(dataroot, file)
        if not file_problems:
            if not isinstance(route, list):
                file_problems = [Problem(file.name, "must be a JSON array of [x, y] points")]
            else:
                bad = next((i for i, p in enumerate(route) if not (isinstance(p, list) and len(p) == 2 and all(
                    type(c) in (int, float) for c in p))), None)
                if bad is not None:
                    file_problems = [Problem(file.name, f"point is not [x, y] (two numbers): {json.dumps(route[bad])[:60]}", bad)]
        problems += file_problems
        if file_problems:
            continue
        starts.append(len(records))
        records += route
        scene_names += [file.scene] * len(route)
    if problems:
        return None, problems
    big = next((i for i, p in enumerate(records) for c in p if type(c) is int and abs(c) > 2**53), None)
    if big is not None:
        file, index = Located([f.name for f in files], starts).where(big)
        return None, [Problem(file, "point coordinate is an integer beyond 2**53 (would not convert exactly)", index)]
    int_values = {axis: [i for i, p in enumerate(records) if type(p[k]) is int] for k, axis in enumerate("xy")}
    index = [i - s for s, e in zip(starts, starts[1:] + [len(records)]) for i in range(s, e)]
    table = pa.table({"scene_name": pa.array(scene_names, pa.string()), "point_index": pa.array(index, pa.int32()),
                      "x": pa.array([float(p[0]) for p in records], pa.float64()),
                      "y": pa.array([float(p[1]) for p in records], pa.float64())})
    columns = Columns(table, ["x", "y"], int_values={k: v for k, v in int_values.items() if v})
    return Read(table, columns, list(files), starts), []
