"""`can_bus/<message>/` (one dataset per CAN message type found), `can_bus/meta/` and `can_bus/route/`: the CAN bus
expansion files of the converted scenes, typed by inference, sorted by scene and time, exactly reversible."""

from __future__ import annotations

import pyarrow as pa

from nuparquet.conversion.builder import BuildContext, Builder, needs_folder
from nuparquet.problems import ProblemsFound
from nuparquet.sources import can_bus as source
from nuparquet.sources.json_records import range_facts

FILE_KIND = {source.META: "can_bus_meta", source.ROUTE: "can_bus_route"}


def build(ctx: BuildContext) -> dict[str, pa.Table]:
    scenes = set(ctx.tables["scene"]["name"].to_list())
    found, _others = source.discover(ctx.dataroot, scenes)
    out, problems = {}, []
    for message, files in found.items():
        if ctx.reporter:
            ctx.reporter.note(f"can_bus {message}")
        reader = {source.META: source.read_meta, source.ROUTE: source.read_route}.get(message, source.read_messages)
        read, read_problems = reader(ctx.dataroot, files)
        problems += read_problems
        if read is None:
            continue
        name = f"{source.FOLDER}/{message}"
        out[name] = read.table
        ctx.files += _file_entries(read, name, FILE_KIND.get(message, "can_bus_messages"))
    if problems:
        raise ProblemsFound(problems)
    return out


def _file_entries(read: source.Read, dataset: str, kind: str) -> list[dict]:
    """One manifest entry per file, with what export-json needs to write it back (positions file-local)."""
    columns = read.columns
    stops = read.starts[1:] + [read.table.num_rows]
    entries = []
    for file, start, stop in zip(read.files, read.starts, stops):
        entry = {"path": file.name, "kind": kind, "dataset": dataset, "scene": file.scene, "keys": columns.keys}
        if columns.json_fields:
            entry["json_fields"] = columns.json_fields
        entry |= range_facts(columns, start, stop)
        entries.append(entry)
    return entries


BUILDER = Builder("can_bus", build, scope="whole", wanted=needs_folder(source.FOLDER))
