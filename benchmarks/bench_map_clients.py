"""Row 17: six real map clients (tests/parity/map_clients.py) on `nuparquet.devkit.map_expansion` vs the devkit's.

    .venv/bin/python benchmarks/bench_map_clients.py [--scenes 100] [--samples 400] [--devkit-samples 20]
        [--clients hdmapnet,maptr,streammapnet,bevfusion,pgp,trajdata]

Data: `nuparquet synth --scenes N --samples-per-scene 40 --no-can-bus` (tables and maps: every scene's roads go into
its location's map, so 100 scenes make four ~11 MB map files) converted once into `.bench-cache/map-clients/`
(under NUPARQUET_BENCH_CACHE when set); our side reads a copy of the dataroot without `maps/expansion/`.

In one process, the sides alternating client by client, each on maps built afresh for it:
- construction: `NuScenesMap(dataroot, location)` of the four maps, each side (ours builds its records lazily: what
  a client first asks for is paid inside that client's loop, not here);
- each per-keyframe client (HDMapNet, MapTR v2, StreamMapNet, bevfusion, PGP) over the first `--samples` keyframes
  of a seeded shuffle of all of them (0: every keyframe) on ours, and the first `--devkit-samples` of those on the
  devkit (its cost per keyframe is flat, a scan of every record of the map per call), each rate in keyframes/s;
  the answers of the devkit's keyframes are checked equal to ours (`tests/parity/geometry_same.py`);
- trajdata: `populate_vector_map` of the four maps, each side, checked equal.
The devkit's `mask_for_lines` raises under shapely 2 wherever a divider is cut in pieces by the patch (bevfusion
meets that within a few keyframes); it is replaced by its shapely 1 behaviour (`map_clients.
mask_for_lines_as_in_shapely_1`) so that the devkit has an answer to time and compare.
Times are CPU seconds of this process (`time.process_time`; both sides single-threaded): on a shared box the wall
time mostly measures the neighbours (the wall times are written too). The ratio is the devkit's CPU seconds per
keyframe over ours. Prints the rows and writes
benchmarks/results/<UTC time>-map_clients.json.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "parity"))
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))  # this checkout's nuparquet
from bench_data import CACHE as BENCH_CACHE  # noqa: E402
from harness import Row, log, report_alone, seconds, times  # noqa: E402

CACHE = BENCH_CACHE / "map-clients"
VERSION = "v1.0-trainval"
PER_KEYFRAME = ("hdmapnet", "maptr", "streammapnet", "bevfusion", "pgp")
TARGET = 10.0


def make_data(scenes: int) -> tuple[Path, Path, Path]:
    """(the dataroot, its copy without the map JSON, the conversion)."""
    root, bare, out = CACHE / "data", CACHE / "data-no-map-json", CACHE / "out"
    marker = CACHE / f".scenes-{scenes}"
    if not marker.exists():
        shutil.rmtree(CACHE, ignore_errors=True)
        CACHE.mkdir(parents=True)
        from nuparquet.conversion import convert
        from nuparquet.synth import synthesize

        log(f"synthesising {scenes} scenes (tables and maps) into {root}")
        synthesize(root, scenes=scenes, samples_per_scene=40, seed=0, version=VERSION, with_can_bus=False)
        log(f"converting into {out}")
        convert(root, VERSION, out)
        shutil.copytree(root, bare, ignore=shutil.ignore_patterns("expansion"))
        marker.touch()
    return root, bare, out


def run_client(name: str, side: dict, poses: list[dict]):
    import map_clients as mc

    if name == "hdmapnet":
        return mc.hdmapnet_samples(side["map_api"], side["maps"], poses)
    if name == "maptr":
        return mc.maptr_infos(side["map_api"], side["maps"], poses)
    if name == "streammapnet":
        return mc.streammapnet_samples(side["map_api"], side["maps"], poses)
    if name == "bevfusion":
        return mc.bevfusion_samples(side["maps"], poses)
    if name == "pgp":
        return mc.pgp_samples(side["maps"], poses)
    if name == "trajdata":
        return mc.trajdata_maps(side["arcline_path_utils"](), side["maps"])
    raise SystemExit(f"unknown client {name!r}")


MAP_PACKAGES = (os.path.join("", "nuscenes", "map_expansion", ""),
                os.path.join("", "nuparquet", "devkit", "map_expansion", ""))


def map_api_seconds(name: str, side: dict, poses: list[dict]) -> tuple[float, float]:
    """(the client's seconds under cProfile, the part of them inside the map expansion's functions when called from
    outside it: the client's calls of the map API, everything they call included)."""
    import cProfile
    import pstats

    profile = cProfile.Profile()
    profile.enable()
    run_client(name, side, poses)
    profile.disable()
    stats = pstats.Stats(profile).stats
    inside = lambda func: any(package in func[0] for package in MAP_PACKAGES)  # noqa: E731
    total = max(entry[3] for entry in stats.values())
    in_map_api = sum(edge[3] for func, entry in stats.items() if inside(func)
                     for caller, edge in entry[4].items() if not inside(caller))
    return total, in_map_api


def build_side(which: str, root: Path, bare: Path, out: Path, locations: list[str]) -> tuple[dict, float]:
    """The side's modules and its four maps, and the seconds their construction took."""
    import importlib

    package = "nuscenes.map_expansion" if which == "devkit" else "nuparquet.devkit.map_expansion"
    map_api = importlib.import_module(f"{package}.map_api")
    start = time.process_time()
    if which == "devkit":
        maps = {location: map_api.NuScenesMap(str(root), location) for location in locations}
    else:
        maps = {location: map_api.NuScenesMap(str(bare), location, parquet=out) for location in locations}
    built_s = time.process_time() - start
    return dict(map_api=map_api, maps=maps,
                arcline_path_utils=lambda: importlib.import_module(f"{package}.arcline_path_utils")), built_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=100)
    parser.add_argument("--samples", type=int, default=400, help="keyframes for ours (0: every keyframe)")
    parser.add_argument("--devkit-samples", type=int, default=20, help="keyframes for the devkit (a prefix of ours)")
    parser.add_argument("--clients", default=",".join(PER_KEYFRAME + ("trajdata",)))
    parser.add_argument("--profile", type=int, default=0,
                        help="also profile each side on this many of the devkit's keyframes: the map API's share")
    args = parser.parse_args()

    import numpy as np
    from geometry_same import canonical, differences
    from map_clients import keyframe_poses
    from nuscenes.nuscenes import NuScenes

    from map_clients import mask_for_lines_as_in_shapely_1
    from nuscenes.map_expansion.map_api import NuScenesMapExplorer

    NuScenesMapExplorer.mask_for_lines = staticmethod(mask_for_lines_as_in_shapely_1)
    root, bare, out = make_data(args.scenes)
    nusc = NuScenes(VERSION, str(root), verbose=False)
    poses = keyframe_poses(nusc)
    order = np.random.default_rng(0).permutation(len(poses))
    poses = [poses[i] for i in order]
    ours_poses = poses if args.samples == 0 else poses[:args.samples]
    devkit_poses = ours_poses[:args.devkit_samples]
    locations = sorted(p.stem for p in (root / "maps" / "expansion").glob("*.json"))
    log(f"{len(poses)} keyframes; ours run {len(ours_poses)}, the devkit {len(devkit_poses)}; maps {locations}")

    rows, figures = [], {}
    construction = {"devkit": [], "ours": []}
    for client in args.clients.split(","):
        timings, walls, answers, shares = {}, {}, {}, {}
        for which in ("devkit", "ours"):
            side, built_s = build_side(which, root, bare, out, locations)
            construction[which].append(built_s)
            subset = devkit_poses if which == "devkit" else ours_poses
            start, start_cpu = time.perf_counter(), time.process_time()
            answer = run_client(client, side, subset)
            timings[which] = time.process_time() - start_cpu
            walls[which] = time.perf_counter() - start
            answers[which] = answer
            log(f"  {client} {which}: {timings[which]:.2f} s CPU, {walls[which]:.2f} s wall "
                f"({built_s:.2f} s construction)")
            if args.profile and client != "trajdata":
                total, in_map_api = map_api_seconds(client, side, subset[:args.profile])
                shares[which] = in_map_api / total
                log(f"    profiled on {args.profile}: {in_map_api:.2f} of {total:.2f} s in the map API")
        if client == "trajdata":
            expected, got = answers["devkit"], answers["ours"]
            per = {w: timings[w] / len(locations) for w in timings}
            unit = "map"
        else:
            expected, got = answers["devkit"], answers["ours"][:len(devkit_poses)]
            per = {"devkit": timings["devkit"] / len(devkit_poses), "ours": timings["ours"] / len(ours_poses)}
            unit = "keyframe"
        found = differences(canonical(got), canonical(expected))
        if found:
            raise SystemExit(f"{client}: the answers differ: " + "; ".join(found))
        ratio = per["devkit"] / per["ours"]
        whole_note = (f"; share of the time in the map API (profiled): devkit {shares['devkit']:.0%}, "
                      f"ours {shares['ours']:.0%}") if shares else ""
        figures[client] = dict(per_cpu_s=per, cpu_s=timings, wall_s=walls, unit=unit, ratio=ratio, map_api_share=shares,
                               devkit_samples=len(devkit_poses), ours_samples=len(ours_poses))
        whole = f"; every keyframe ({len(poses)}): ours {seconds(per['ours'] * len(poses))}, " \
                f"devkit {seconds(per['devkit'] * len(poses))}" if unit == "keyframe" else ""
        rows.append(Row(f"17 {client}: per {unit}", seconds(per["ours"]), seconds(per["devkit"]), times(ratio),
                        f"≥ {TARGET:.0f}×", ratio >= TARGET, note=f"{client}: answers equal{whole}{whole_note}",
                        id=f"17{client[0]}"))
    build = {w: float(np.median(v)) for w, v in construction.items()}
    rows.insert(0, Row(f"17 construction: NuScenesMap x {len(locations)}", seconds(build["ours"]),
                       seconds(build["devkit"]), times(build["devkit"] / build["ours"]), "≥ 50×",
                       build["devkit"] / build["ours"] >= 50, note="median over the clients' fresh builds", id="17c"))
    report_alone({"name": "map_clients", "rows": rows, "figures": figures, "construction_s": construction,
                  "keyframes": len(poses), "args": vars(args)})


if __name__ == "__main__":
    main()
