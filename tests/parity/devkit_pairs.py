"""The datasets every `nuparquet.devkit` parity test runs on, each opened twice: by nuscenes-devkit from its JSON and
by `nuparquet.devkit.NuScenes` from its conversion."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit imports pyplot; never open a window

from conftest import EXTRACT_VERSION, IRREGULAR_EMPTY_VERSION, IRREGULAR_VERSION, SYNTH_VERSION

# name -> (dataroot fixture, converted-output fixture, version)
DATASETS = {
    "synth": ("synth_root", "synth_out", SYNTH_VERSION),
    "irregular": ("irregular_root", "irregular_out", IRREGULAR_VERSION),
    "irregular_empty": ("irregular_root", "irregular_empty_out", IRREGULAR_EMPTY_VERSION),
    "layouts": ("layouts_root", "layouts_out", SYNTH_VERSION),
    "labelled": ("labelled_root", "labelled_out", SYNTH_VERSION),
    "extract": ("extract_root", "extract_out", EXTRACT_VERSION),
}


@dataclass
class Pair:
    name: str
    root: Path
    out: Path
    version: str
    theirs: object  # nuscenes.nuscenes.NuScenes
    ours: object  # nuparquet.devkit.NuScenes


def open_pair(request, devkit, name: str) -> Pair:
    from nuparquet.devkit import NuScenes

    root_fixture, out_fixture, version = DATASETS[name]
    root, out = request.getfixturevalue(root_fixture), request.getfixturevalue(out_fixture)
    theirs = devkit.NuScenes(version, dataroot=str(root), verbose=False)
    ours = NuScenes(version, dataroot=str(root), parquet=out, verbose=False)
    return Pair(name, root, out, version, theirs, ours)


def box_values(box) -> dict:
    """Every attribute of a devkit `Box` (nuparquet's or the devkit's), for an exact comparison."""
    return {"center": box.center, "wlh": box.wlh, "orientation": box.orientation.q, "label": box.label,
            "score": box.score, "velocity": box.velocity, "name": box.name, "token": box.token}
