"""Devkit map row: `nuparquet.devkit.map_expansion.map_api.NuScenesMap` vs the devkit's `NuScenesMap` on the largest
synthetic map, in one run.

    .venv/bin/python benchmarks/devkit_map.py [--scenes 200] [--repeats 3]

Data: bench_map.py's (`nuparquet synth --scenes N`, tables only, converted once, under NUPARQUET_BENCH_CACHE); the
largest `maps/expansion/<location>.json` is measured. Each side runs in a fresh process, its library imported
before the clock starts (wall time of each step in-process, peak RSS of the process):
- construct: `NuScenesMap(...)` (the devkit: json.load, indexes, shortcuts; ours: the manifest);
- get_map_mask: one 100 m x 100 m patch at 10 px/m (1000 x 1000), every polygon layer and the dividers, first call
  (ours reads the geometry and builds the trees there) then a second patch; checked pixel-equal;
- record walk: what map clients do per map (HDMapNet, PGP): for every lane, its polygon's exterior node coordinates
  through `get('polygon', ...)` / `get('node', ...)`, and every lane's outgoing lanes; ours rebuilds the layers it
  touches on first access, which is counted here; checked equal.
Prints rows 17a-17c and writes benchmarks/results/<UTC time>-devkit_map.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_map import CACHE, LAYERS, largest_map, make_data  # noqa: E402
from harness import Row, log, megabytes, python_child, repeat, seconds, summarize  # noqa: E402


def _patches(root: Path, location: str) -> list[tuple]:
    data = json.loads((root / "maps" / "expansion" / f"{location}.json").read_text())
    xy = np.array([[node["x"], node["y"]] for node in data["node"]])
    return [(float(x), float(y), 100.0, 100.0) for x, y in (xy[len(xy) // 2], xy[len(xy) // 3])]


def _walk(nusc_map) -> tuple[float, int]:
    """(sum of the lanes' exterior node x, number of outgoing links): a client's loop over records."""
    total, links = 0.0, 0
    for lane in nusc_map.lane:
        polygon = nusc_map.get('polygon', lane['polygon_token'])
        total += sum(nusc_map.get('node', t)['x'] for t in polygon['exterior_node_tokens'])
        links += len(nusc_map.get_outgoing_lane_ids(lane['token']))
    return total, links


def child(side: str, dataroot: str, out: str, location: str) -> None:
    patches = [tuple(p) for p in json.loads((CACHE / "devkit_map_patches.json").read_text())]
    started = time.perf_counter()
    if side == "ours":
        from nuparquet.devkit.map_expansion.map_api import NuScenesMap

        t0 = time.perf_counter()
        nusc_map = NuScenesMap(out, location)
    else:
        from nuscenes.map_expansion.map_api import NuScenesMap

        t0 = time.perf_counter()
        nusc_map = NuScenesMap(dataroot, location)
    import_s = t0 - started
    t1 = time.perf_counter()
    first = nusc_map.get_map_mask(patches[0], 0.0, LAYERS[:8] + ["road_divider"], (1000, 1000))
    t2 = time.perf_counter()
    second = nusc_map.get_map_mask(patches[1], 30.0, LAYERS[:8] + ["road_divider"], (1000, 1000))
    t3 = time.perf_counter()
    walked = _walk(nusc_map)
    t4 = time.perf_counter()
    assert _walk(nusc_map) == walked
    t5 = time.perf_counter()
    np.save(CACHE / f"devkit_map-{side}-mask.npy", np.stack([first, second]))
    print(json.dumps({"construct_s": t1 - t0, "mask_first_s": t2 - t1, "mask_second_s": t3 - t2,
                      "walk_s": t4 - t3, "walk_again_s": t5 - t4, "import_s": import_s, "walk": walked, "lanes": len(nusc_map.lane)}))


def run(repeats: int = 3, scenes: int = 200) -> dict:
    root, out = make_data(scenes)
    location = largest_map(root)
    path = root / "maps" / "expansion" / f"{location}.json"
    log(f"row 17: map {location} ({path.stat().st_size / 2**20:.1f} MiB): devkit face vs the devkit's NuScenesMap")
    (CACHE / "devkit_map_patches.json").write_text(json.dumps(_patches(root, location)))
    keys = {k: k for k in ("construct_s", "mask_first_s", "mask_second_s", "walk_s", "walk_again_s", "import_s")}
    commands = {side: python_child(__file__, "--child", side, str(root), str(out), location) for side in ("ours", "devkit")}
    ours_runs = repeat(commands["ours"], repeats, label="nuparquet.devkit NuScenesMap")
    devkit_runs = repeat(commands["devkit"], repeats, label="devkit NuScenesMap")
    ours, devkit = summarize(ours_runs, **keys), summarize(devkit_runs, **keys)
    same_mask = bool(np.array_equal(np.load(CACHE / "devkit_map-ours-mask.npy"),
                                    np.load(CACHE / "devkit_map-devkit-mask.npy")))
    same_walk = ours_runs[0].report["walk"] == devkit_runs[0].report["walk"]
    result = {
        "name": "devkit_map", "location": location, "map_mib": path.stat().st_size / 2**20,
        "lanes": ours_runs[0].report["lanes"], "ours": ours, "devkit": devkit,
        "speedup_construct": devkit["construct_s"] / ours["construct_s"],
        "speedup_mask_first": devkit["mask_first_s"] / ours["mask_first_s"],
        "speedup_mask_second": devkit["mask_second_s"] / ours["mask_second_s"],
        "speedup_walk": devkit["walk_s"] / ours["walk_s"],
        "rss_ratio": devkit["max_rss_mb"] / ours["max_rss_mb"],
        "same_mask": same_mask, "same_walk": same_walk,
        "commands": {side: " ".join(map(str, cmd)) for side, cmd in commands.items()},
    }
    what = f"devkit face, map {location} ({result['map_mib']:.1f} MiB)"
    result["rows"] = [
        Row(id="17a", benchmark=f"{what}: NuScenesMap(...) construction", ours=seconds(ours["construct_s"]),
            reference=f"devkit {seconds(devkit['construct_s'])}", ratio=f"{result['speedup_construct']:,.0f}x",
            target="≥ 50x", met=result["speedup_construct"] >= 50),
        Row(id="17b", benchmark=f"{what}: get_map_mask, 100 m patch, 1000 x 1000, 9 layers, first / second call",
            ours=f"{seconds(ours['mask_first_s'])} / {seconds(ours['mask_second_s'])}",
            reference=f"devkit {seconds(devkit['mask_first_s'])} / {seconds(devkit['mask_second_s'])}",
            ratio=f"{result['speedup_mask_first']:.1f}x / {result['speedup_mask_second']:.1f}x",
            target="≥ 10x, pixel-equal", met=result["speedup_mask_second"] >= 10 and same_mask),
        Row(id="17c", benchmark=f"{what}: record walk ({result['lanes']:,} lanes: polygon, nodes, outgoing), first "
            "(ours builds the layers it touches) / again; construction + first walk",
            ours=f"{seconds(ours['walk_s'])} / {seconds(ours['walk_again_s'])}; "
            f"{seconds(ours['construct_s'] + ours['walk_s'])}",
            reference=f"devkit {seconds(devkit['walk_s'])} / {seconds(devkit['walk_again_s'])}; "
            f"{seconds(devkit['construct_s'] + devkit['walk_s'])}",
            ratio=f"{result['speedup_walk']:.2f}x / {devkit['walk_again_s'] / ours['walk_again_s']:.2f}x; "
            f"{(devkit['construct_s'] + devkit['walk_s']) / (ours['construct_s'] + ours['walk_s']):.1f}x",
            target="report, same answers", met=None,
            note=f"row 17: whole processes {seconds(ours['wall_s'])} / {megabytes(ours['max_rss_mb'])} (ours) and "
            f"{seconds(devkit['wall_s'])} / {megabytes(devkit['max_rss_mb'])} (devkit): peak RSS "
            f"{result['rss_ratio']:.2f}x the devkit's; module imports {seconds(ours['import_s'])} (ours) and "
            f"{seconds(devkit['import_s'])} (devkit), outside the construction; same answers: mask {same_mask}, "
            f"walk {same_walk}"),
    ]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(*args.child)
        return
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes))


if __name__ == "__main__":
    main()
