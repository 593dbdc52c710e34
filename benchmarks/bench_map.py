"""Map row: the largest synthetic map, `nuparquet.map.queries.MapLayers` vs the devkit's `NuScenesMap`, in one run.

    .venv/bin/python benchmarks/bench_map.py [--scenes 200] [--points 10000] [--devkit-points 100] [--repeats 3]

Data: `.bench-cache/map/` (under NUPARQUET_BENCH_CACHE when set) — `nuparquet synth --scenes N` (tables only; every scene's road goes into the map of its
location) converted once; the largest `maps/expansion/<location>.json` is measured.

Measured, each side in a fresh process (wall time of each step in-process, peak RSS of the process):
- load: `NuScenesMap(dataroot, location)` (json.load + indices) vs `nuparquet.open(OUT).map(location)` (WKB from
  the GeoParquet, shapely arrays; the STRtrees are built on first use and counted in the first query);
- layers_on_point and closest_lane (radius 5 m) for `--points` points (half near the roads, half anywhere on the
  map): nuparquet answers all of them; the devkit answers the first `--devkit-points` (its per-point cost is
  flat, a full scan of the layers) and its time is extrapolated to all the points; the answers on that sample are
  checked equal;
- map_mask: one 100 m x 100 m patch at 10 px/m (1000 x 1000), every polygon and line layer, checked pixel-equal.
Prints rows 9a-9d and writes benchmarks/results/<UTC time>-map.json; `run_all.py` runs it as `map`.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_data import CACHE as BENCH_CACHE  # noqa: E402
from harness import Row, log, megabytes, python_child, repeat, seconds, summarize  # noqa: E402

CACHE = BENCH_CACHE / "map"
LAYERS = ["drivable_area", "road_segment", "road_block", "lane", "ped_crossing", "walkway", "stop_line",
          "carpark_area", "road_divider", "lane_divider"]


def make_data(scenes: int) -> tuple[Path, Path]:
    root, out = CACHE / "data", CACHE / "out"
    marker = CACHE / f".scenes-{scenes}"
    if marker.exists():
        return root, out
    shutil.rmtree(CACHE, ignore_errors=True)
    CACHE.mkdir(parents=True)
    from nuparquet.conversion import convert
    from nuparquet.synth import synthesize

    log(f"synthesising {scenes} scenes (tables and maps) into {root}")
    synthesize(root, scenes=scenes, samples_per_scene=40, seed=0, version="v1.0-synth", with_can_bus=False)
    log(f"converting into {out}")
    convert(root, "v1.0-synth", out)
    marker.touch()
    return root, out


def largest_map(root: Path) -> str:
    return max((root / "maps" / "expansion").glob("*.json"), key=lambda p: p.stat().st_size).stem


def queries(root: Path, location: str, n: int) -> tuple[np.ndarray, tuple]:
    """The query points (n, 2) and the mask patch, the same for both sides."""
    data = json.loads((root / "maps" / "expansion" / f"{location}.json").read_text())
    xy = np.array([[node["x"], node["y"]] for node in data["node"]])
    rng = np.random.default_rng(0)
    near = xy[rng.integers(0, len(xy), n // 2)] + rng.normal(0.0, 5.0, (n // 2, 2))
    anywhere = rng.uniform(xy.min(axis=0), xy.max(axis=0), (n - n // 2, 2))
    points = np.r_[near, anywhere]
    rng.shuffle(points)
    centre = xy[len(xy) // 2]
    return points, (float(centre[0]), float(centre[1]), 100.0, 100.0)


def _load_queries() -> tuple[np.ndarray, tuple]:
    """The points and patch the parent wrote (so neither side pays for making them)."""
    return np.load(CACHE / "points.npy"), tuple(json.loads((CACHE / "patch.json").read_text()))


def child_ours(root: str, out: str, location: str, n: str) -> None:
    points, patch = _load_queries()
    t0 = time.perf_counter()
    import nuparquet

    m = nuparquet.open(out).map(location)
    t1 = time.perf_counter()
    on = m.layers_on_point(points[:, 0], points[:, 1])
    t2 = time.perf_counter()
    closest = m.closest_lane(points[:, 0], points[:, 1], 5.0)
    t3 = time.perf_counter()
    mask = m.map_mask(patch, 0.0, LAYERS, (1000, 1000))
    t4 = time.perf_counter()
    np.save(Path(out).parent / "ours-mask.npy", mask)
    print(json.dumps({"load_s": t1 - t0, "layers_on_point_s": t2 - t1, "closest_lane_s": t3 - t2, "map_mask_s": t4 - t3,
                      "on": {k: v[:2000].tolist() for k, v in on.items()}, "closest": closest[:2000].tolist()}))


def child_devkit(root: str, out: str, location: str, n: str, k: str) -> None:
    points, patch = _load_queries()
    points = points[:int(k)]
    t0 = time.perf_counter()
    from nuscenes.map_expansion.map_api import NuScenesMap

    m = NuScenesMap(root, location)
    t1 = time.perf_counter()
    on = [m.layers_on_point(x, y) for x, y in points]
    t2 = time.perf_counter()
    closest = [m.get_closest_lane(x, y, 5.0) for x, y in points]
    t3 = time.perf_counter()
    try:
        mask = m.get_map_mask(patch, 0.0, LAYERS, (1000, 1000))
        mask_ok = True
    except TypeError:  # a clipped MultiLineString: the devkit cannot iterate it under shapely 2
        mask = m.get_map_mask(patch, 0.0, LAYERS[:8], (1000, 1000))
        mask_ok = False
    t4 = time.perf_counter()
    np.save(Path(out).parent / "devkit-mask.npy", mask)
    print(json.dumps({"load_s": t1 - t0, "layers_on_point_s": t2 - t1, "closest_lane_s": t3 - t2, "map_mask_s": t4 - t3,
                      "mask_all_layers": mask_ok, "points": len(points),
                      "on": {layer: [r[layer] for r in on] for layer in on[0]}, "closest": closest}))


def run(repeats: int = 3, scenes: int = 200, points_n: int = 10_000, devkit_points: int = 100,
        devkit_repeats: int | None = None) -> dict:
    """Row 9: `MapLayers` vs `NuScenesMap` on the largest synthetic map (load, the two point queries, the mask)."""
    root, out = make_data(scenes)
    location = largest_map(root)
    path = root / "maps" / "expansion" / f"{location}.json"
    log(f"row 9: map {location} ({path.stat().st_size / 2**20:.1f} MiB): MapLayers vs NuScenesMap")
    points, patch = queries(root, location, points_n)
    np.save(CACHE / "points.npy", points)
    (CACHE / "patch.json").write_text(json.dumps(patch))
    keys = {k: k for k in ("load_s", "layers_on_point_s", "closest_lane_s", "map_mask_s")}
    ours_cmd = python_child(__file__, "--child", "ours", str(root), str(out), location, str(points_n))
    devkit_cmd = python_child(__file__, "--child", "devkit", str(root), str(out), location, str(points_n),
                              str(devkit_points))
    ours_runs = repeat(ours_cmd, repeats, label="nuparquet MapLayers")
    devkit_runs = repeat(devkit_cmd, devkit_repeats or repeats, label="devkit NuScenesMap")
    ours, devkit = summarize(ours_runs, **keys), summarize(devkit_runs, **keys)
    k, n = devkit_points, points_n
    a, b = ours_runs[0].report, devkit_runs[0].report
    same_on = all(a["on"][layer][:k] == b["on"][layer] for layer in b["on"])
    same_closest = a["closest"][:k] == b["closest"]
    devkit_mask = np.load(CACHE / "devkit-mask.npy")
    same_mask = bool(np.array_equal(np.load(CACHE / "ours-mask.npy")[:len(devkit_mask)], devkit_mask))
    scale = n / k
    data = json.loads(path.read_text())
    result = {
        "name": "map", "location": location, "map_mib": path.stat().st_size / 2**20,
        "records": {layer: len(data[layer]) for layer in ("node", "polygon", "line", "lane", "lane_connector")},
        "points": n, "devkit_points": k, "ours": ours, "devkit": devkit,
        "devkit_layers_on_point_extrapolated_s": devkit["layers_on_point_s"] * scale,
        "devkit_closest_lane_extrapolated_s": devkit["closest_lane_s"] * scale,
        "speedup_load": devkit["load_s"] / ours["load_s"],
        "speedup_layers_on_point": devkit["layers_on_point_s"] * scale / ours["layers_on_point_s"],
        "speedup_closest_lane": devkit["closest_lane_s"] * scale / ours["closest_lane_s"],
        "speedup_map_mask": devkit["map_mask_s"] / ours["map_mask_s"],
        "rss_ratio": devkit["max_rss_mb"] / ours["max_rss_mb"],
        "same_layers_on_point": same_on, "same_closest_lane": same_closest, "same_mask": same_mask,
        "devkit_mask_all_layers": b["mask_all_layers"],
        "commands": {"ours": " ".join(map(str, ours_cmd)), "devkit": " ".join(map(str, devkit_cmd))},
    }
    what = f"map {location} ({result['map_mib']:.1f} MiB)"
    result["rows"] = [
        Row(id="9a", benchmark=f"{what}: open / load", ours=seconds(ours["load_s"]),
            reference=f"NuScenesMap {seconds(devkit['load_s'])}", ratio=f"{result['speedup_load']:.1f}x",
            target="report", met=None),
        Row(id="9b", benchmark=f"{what}: layers_on_point, {n:,} points, 8 layers", ours=seconds(ours["layers_on_point_s"]),
            reference=f"{seconds(devkit['layers_on_point_s'])} for {k} -> {seconds(devkit['layers_on_point_s'] * scale)} "
            f"for {n:,} (extrapolated)", ratio=f"{result['speedup_layers_on_point']:,.0f}x", target="≥ 100x, same answers",
            met=result["speedup_layers_on_point"] >= 100 and same_on),
        Row(id="9c", benchmark=f"{what}: closest_lane, {n:,} points, radius 5 m", ours=seconds(ours["closest_lane_s"]),
            reference=f"{seconds(devkit['closest_lane_s'])} for {k} -> {seconds(devkit['closest_lane_s'] * scale)} "
            f"for {n:,} (extrapolated)", ratio=f"{result['speedup_closest_lane']:,.0f}x", target="≥ 100x, same answers",
            met=result["speedup_closest_lane"] >= 100 and same_closest),
        Row(id="9d", benchmark=f"{what}: map_mask, 100 m patch, 1000 x 1000, 10 layers", ours=seconds(ours["map_mask_s"]),
            reference=f"get_map_mask {seconds(devkit['map_mask_s'])}", ratio=f"{result['speedup_map_mask']:.1f}x",
            target="pixel-equal", met=same_mask,
            note=f"row 9: whole processes {seconds(ours['wall_s'])} / {megabytes(ours['max_rss_mb'])} (ours) and "
            f"{seconds(devkit['wall_s'])} / {megabytes(devkit['max_rss_mb'])} (devkit, {k} points); same answers: "
            f"layers_on_point {same_on}, closest_lane {same_closest}, mask {same_mask}"),
    ]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=200)
    parser.add_argument("--points", type=int, default=10_000)
    parser.add_argument("--devkit-points", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        {"ours": child_ours, "devkit": child_devkit}[args.child[0]](*args.child[1:])
        return
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes, args.points, args.devkit_points))


if __name__ == "__main__":
    main()
