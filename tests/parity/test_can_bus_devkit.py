"""CAN bus datasets against nuscenes-devkit's NuScenesCanBus (real extract and synthetic files): every message
field for field, meta and route; and the exported files equal to the originals, JSON types and key order too."""

from __future__ import annotations

import json
import os

import polars as pl
import pytest

from nuparquet.export.json_files import export_json

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="module", params=["extract", "synth", "wild"])
def case(request):
    if request.param == "extract":
        root, out = request.getfixturevalue("extract_root"), request.getfixturevalue("extract_out")
    elif request.param == "wild":  # the shapes real files take beyond ours (synth.can_bus, wild)
        root, out = request.getfixturevalue("wild_can_root"), request.getfixturevalue("wild_can_out")
    else:
        root, out = request.getfixturevalue("synth_root"), request.getfixturevalue("synth_out")
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus

    return root, out, NuScenesCanBus(dataroot=str(root))


def _files(root):
    return sorted((root / "can_bus").glob("scene-*_*.json"))


def _scene_message(path):
    scene, message = path.stem.split("_", 1)
    return scene, message


def test_every_message_equals_devkit_get_messages(case):
    root, out, can = case
    checked = 0
    for path in _files(root):
        scene, message = _scene_message(path)
        if message in ("meta", "route"):
            continue
        expected = can.get_messages(scene, message)
        ours = (pl.read_parquet(out / "can_bus" / message).filter(pl.col("scene_name") == scene)
                .drop("scene_name").to_dicts())
        assert len(ours) == len(expected) > 0, (scene, message)
        for mine, theirs in zip(ours, expected):
            assert set(mine) == set(theirs)
            for key, value in theirs.items():
                assert mine[key] == value, (scene, message, key)
        checked += 1
    assert checked >= 4


def test_messages_are_sorted_by_scene_and_time_with_scene_and_utime_first(case):
    _, out, _ = case
    for folder in (out / "can_bus").iterdir():
        if folder.name in ("meta", "route"):
            continue
        df = pl.read_parquet(folder)
        assert df.columns[:2] == ["scene_name", "utime"] and df.schema["utime"] == pl.Int64
        assert df.equals(df.sort("scene_name", "utime", maintain_order=True))


def test_meta_and_route_equal_devkit(case):
    root, out, can = case
    meta = pl.read_parquet(out / "can_bus" / "meta")
    route = pl.read_parquet(out / "can_bus" / "route")
    scenes = sorted({_scene_message(p)[0] for p in _files(root)})
    for scene in scenes:
        expected = can.get_messages(scene, "meta")  # keys lower-cased by the devkit
        rows = meta.filter(pl.col("scene_name") == scene).to_dicts()
        ours = {}
        for row in rows:
            name = row.pop("message").lower()
            row.pop("scene_name")
            row["var_stats"] = None if row["var_stats"] is None else json.loads(row["var_stats"])
            ours[name] = row
        assert ours == expected, scene
        points = route.filter(pl.col("scene_name") == scene).sort("point_index")
        assert [[x, y] for x, y in zip(points["x"], points["y"])] == can.get_messages(scene, "route")
        assert points["point_index"].to_list() == list(range(points.height))


def test_export_json_writes_every_can_bus_file_back_exactly(case, tmp_path):
    root, out, _ = case
    export_json(out, tmp_path / "dataroot")
    originals = _files(root)
    assert sorted(p.name for p in (tmp_path / "dataroot" / "can_bus").iterdir()) == [p.name for p in originals]

    def same(a, b, where):
        assert type(a) is type(b), where  # 0 stays 0, 0.0 stays 0.0
        if isinstance(a, dict):
            assert list(a) == list(b), where  # key order kept
            for k in a:
                same(a[k], b[k], f"{where}.{k}")
        elif isinstance(a, list):
            assert len(a) == len(b), where
            for i, (x, y) in enumerate(zip(a, b)):
                same(x, y, f"{where}[{i}]")
        else:
            assert a == b, where

    for path in originals:
        same(json.loads(path.read_text()), json.loads((tmp_path / "dataroot" / "can_bus" / path.name).read_text()),
             path.name)


def test_the_real_extract_converts_its_can_bus(extract_out):
    manifest = json.loads((extract_out / "manifest.json").read_text())
    datasets = manifest["datasets"]
    # counts from the extract's can_bus/README.md
    assert datasets["can_bus/pose"]["rows"] == 995 + 964
    assert datasets["can_bus/ms_imu"]["rows"] == 1987 + 1942
    assert datasets["can_bus/vehicle_monitor"]["rows"] == 41 + 39
    assert datasets["can_bus/route"]["rows"] == 939 + 1139
    assert datasets["sample_can_bus"]["rows"] == pl.read_parquet(extract_out / "tables/sample").height
    assert {f["path"] for f in manifest["files"] if f["kind"].startswith("can_bus")} == \
        {f"can_bus/scene-{s}_{m}.json" for s in ("0523", "0916")
         for m in ("meta", "ms_imu", "pose", "route", "steeranglefeedback", "vehicle_monitor")}


def test_misaligned_routes_equal_list_misaligned_routes(case, tmp_path):
    """`can_bus.routes.misaligned_routes` = `NuScenesCanBus.list_misaligned_routes` at several thresholds, some scenes
    on each side (the devkit walks every file of can_bus/: the scene files are copied apart from a README)."""
    import shutil

    import numpy as np
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus

    import nuparquet
    from nuparquet.can_bus.routes import misaligned_routes, route_misalignment_m

    root, out, _ = case
    (tmp_path / "can_bus").mkdir()
    for path in _files(root):
        shutil.copy(path, tmp_path / "can_bus" / path.name)
    can = NuScenesCanBus(dataroot=str(tmp_path))
    ds = nuparquet.open(out)
    distances = route_misalignment_m(ds)["misalignment_m"].to_numpy()
    assert len(distances) == len({_scene_message(p)[0] for p in _files(root)})
    for threshold in (0.0, float(np.median(distances)), 5.0):
        assert misaligned_routes(ds, threshold) == can.list_misaligned_routes(max_misalignment=threshold)
    assert misaligned_routes(ds, 0.0) and not misaligned_routes(ds, 5.0)


def test_the_blacklists_are_the_devkits(tmp_path):
    from nuscenes.can_bus.can_bus_api import NuScenesCanBus

    from nuparquet.can_bus import blacklists

    (tmp_path / "can_bus").mkdir()
    can = NuScenesCanBus(dataroot=str(tmp_path))  # the default 5 m: the hard-coded route blacklist
    assert set(can.can_blacklist) == blacklists.CAN_BLACKLIST and len(blacklists.CAN_BLACKLIST) == 21
    assert set(can.route_blacklist) == blacklists.ROUTE_BLACKLIST and len(blacklists.ROUTE_BLACKLIST) == 87
    assert blacklists.scene_number("scene-0161") == 161 and blacklists.scene_number("lyft-scene-x") is None
