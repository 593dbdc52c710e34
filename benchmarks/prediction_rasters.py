"""Row 16: the prediction models' input rasters, `nuparquet.devkit.prediction.input_representation` against
nuscenes-devkit's `nuscenes.prediction.input_representation`, in one run.

    .venv/bin/python benchmarks/prediction_rasters.py [--scenes 200] [--measure-scenes 2] [--devkit-every 10]

Data: row 9's set (`bench_map.make_data`: `nuparquet synth --scenes N --samples-per-scene 40`, tables and maps,
converted once into `.bench-cache/map/`, under NUPARQUET_BENCH_CACHE when set). Measured: the first
`--measure-scenes` scenes on the largest map, every agent of every keyframe ((instance, sample) pairs in
sample_annotation order), the devkit tutorial's input: `InputRepresentation(StaticLayerRasterizer(helper),
AgentBoxesWithFadedHistory(helper, seconds_of_history=1), Rasterizer())`, 500 x 500 px.

Each side is a fresh child process (harness.run_child: wall time, peak RSS), timed in-process in steps: the
imports; construction (`NuScenes`, `PredictHelper`, the rasterizer with its map: the devkit's `NuScenesMap` JSON
load of that one map, ours `Dataset.map`); the rasters. The devkit draws every `--devkit-every`-th pair (its
per-raster cost is flat, a scan of the map's records) and its time per raster is multiplied out to all pairs; ours
draws every pair. Wall and CPU time (`time.process_time`, every thread: OpenCV's warps use two) of the rasters
are both reported: on a shared box the wall time carries the others' load. Both print the SHA-256 of the rasters
they share (every `--devkit-every`-th): they must be equal.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit imports pyplot; never open a window

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_map  # noqa: E402
from harness import Row, log, megabytes, python_child, repeat, seconds, summarize  # noqa: E402

VERSION = "v1.0-synth"


def chosen_pairs(out: Path, location: str, scenes: int) -> list[tuple[str, str]]:
    """Every (instance, sample) of the first `scenes` scenes of `location`, in sample_annotation order."""
    import polars as pl

    tables = out / "tables"
    logs = pl.read_parquet(tables / "log").filter(pl.col("location") == location)["token"]
    names = (pl.read_parquet(tables / "scene").filter(pl.col("log_token").is_in(logs.implode()))
             .sort("name")["token"].head(scenes))
    samples = pl.read_parquet(tables / "sample").filter(pl.col("scene_token").is_in(names.implode()))["token"]
    annotations = pl.read_parquet(tables / "sample_annotation", columns=["instance_token", "sample_token"])
    chosen = annotations.filter(pl.col("sample_token").is_in(samples.implode()))
    return list(zip(chosen["instance_token"].to_list(), chosen["sample_token"].to_list()))


def child(impl: str, root: str, out: str, location: str, scenes: str, every: str) -> None:
    start = time.perf_counter()
    if impl == "devkit":
        from nuscenes.map_expansion.map_api import NuScenesMap
        from nuscenes.nuscenes import NuScenes
        from nuscenes.prediction import PredictHelper
        from nuscenes.prediction.input_representation import static_layers
        from nuscenes.prediction.input_representation.agents import AgentBoxesWithFadedHistory
        from nuscenes.prediction.input_representation.combinators import Rasterizer
        from nuscenes.prediction.input_representation.interface import InputRepresentation
    else:
        from nuparquet.devkit import NuScenes
        from nuparquet.devkit.prediction import PredictHelper
        from nuparquet.devkit.prediction.input_representation import static_layers
        from nuparquet.devkit.prediction.input_representation.agents import AgentBoxesWithFadedHistory
        from nuparquet.devkit.prediction.input_representation.combinators import Rasterizer
        from nuparquet.devkit.prediction.input_representation.interface import InputRepresentation
    imported = time.perf_counter()
    if impl == "devkit":
        nusc = NuScenes(VERSION, dataroot=root, verbose=False)
        # the devkit's load_all_maps reads all four maps' JSON; the measured scenes need one: its load alone
        one_map = {location: NuScenesMap(root, location)}
        static_layers.load_all_maps = lambda helper, verbose=False: one_map
    else:
        nusc = NuScenes(VERSION, dataroot=root, parquet=out, verbose=False)
    helper = PredictHelper(nusc)
    representation = InputRepresentation(static_layers.StaticLayerRasterizer(helper),
                                         AgentBoxesWithFadedHistory(helper, seconds_of_history=1), Rasterizer())
    constructed = time.perf_counter()
    pairs = chosen_pairs(Path(out), location, int(scenes))
    step = int(every) if impl == "devkit" else 1
    digest = hashlib.sha256()
    timed = cpu = 0.0
    for k, (instance, sample) in enumerate(pairs[::step]):
        t, c = time.perf_counter(), time.process_time()
        image = representation.make_input_representation(instance, sample)
        timed += time.perf_counter() - t
        cpu += time.process_time() - c
        if (k * step) % int(every) == 0:
            digest.update(image.tobytes())
    drawn = len(pairs[::step])
    print(json.dumps({"import_s": imported - start, "construct_s": constructed - imported, "rasters_s": timed,
                      "drawn": drawn, "pairs": len(pairs), "per_raster_s": timed / drawn,
                      "per_raster_cpu_s": cpu / drawn,
                      "all_rasters_s": timed / drawn * len(pairs), "digest": digest.hexdigest(),
                      "shape": list(image.shape)}))
    os._exit(0)  # neither side pays for freeing its objects


def run(repeats: int = 1, scenes: int = 200, measure_scenes: int = 2, devkit_every: int = 10) -> dict:
    root, out = bench_map.make_data(scenes)
    location = bench_map.largest_map(root)
    log(f"row 18: prediction rasters on {location}, every agent of {measure_scenes} scenes")
    args = [str(root), str(out), location, str(measure_scenes), str(devkit_every)]
    runs = {"devkit": [], "nuparquet": []}
    for _ in range(repeats):  # interleaved: on a shared box the load then weighs on both alike
        for impl in runs:
            runs[impl] += repeat(python_child(__file__, "--child", impl, *args), 1, label=f"rasters {impl}")
    measured = {impl: summarize(done, import_s="import_s", construct_s="construct_s", per_raster_s="per_raster_s",
                                all_rasters_s="all_rasters_s", per_raster_cpu_s="per_raster_cpu_s")
                | {"report": done[0].report} for impl, done in runs.items()}
    dev, our = measured["devkit"], measured["nuparquet"]
    same = dev["report"]["digest"] == our["report"]["digest"]
    pairs = our["report"]["pairs"]
    map_mb = (root / "maps" / "expansion" / f"{location}.json").stat().st_size / 2**20
    rows = [
        Row(id="16a", benchmark=f"devkit tutorial's input raster (map layers + lanes + agents, 1 s of history, "
                                f"500 x 500) of every agent of {measure_scenes} scenes ({pairs:,} rasters) on "
                                f"{location} ({map_mb:.1f} MiB of map JSON)",
            ours=f"{seconds(our['per_raster_s'])} a raster ({seconds(our['per_raster_cpu_s'])} CPU), "
                 f"{seconds(our['all_rasters_s'])} for all",
            reference=f"devkit {seconds(dev['per_raster_s'])} a raster ({seconds(dev['per_raster_cpu_s'])} CPU; "
                      f"{dev['report']['drawn']:,} drawn), {seconds(dev['all_rasters_s'])} for all (extrapolated)",
            ratio=f"{dev['per_raster_s'] / our['per_raster_s']:.1f}× (CPU "
                  f"{dev['per_raster_cpu_s'] / our['per_raster_cpu_s']:.1f}×)", target="≥ 10x, pixel-equal",
            met=same and dev['per_raster_s'] / our['per_raster_s'] >= 10,
            note=f"row 18a check: the {dev['report']['drawn']:,} shared rasters' digest equal: {same}"),
        Row(id="16b", benchmark=f"construction: `NuScenes`, `PredictHelper`, the rasterizers with the map of "
                                f"{location}",
            ours=f"{seconds(our['construct_s'])} (import {seconds(our['import_s'])}; process "
                 f"{seconds(our['wall_s'])}, {megabytes(our['max_rss_mb'])} peak)",
            reference=f"devkit {seconds(dev['construct_s'])} (import {seconds(dev['import_s'])}; process "
                      f"{seconds(dev['wall_s'])}, {megabytes(dev['max_rss_mb'])} peak)",
            ratio=f"{dev['construct_s'] / our['construct_s']:.1f}×", target="report", met=None),
    ]
    return {"name": "prediction_rasters", "scenes": scenes, "location": location, "pairs": pairs,
            "measured": measured, "same_rasters": same,
            "commands": {impl: " ".join(python_child(__file__, "--child", impl, *args)) for impl in runs},
            "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=200)
    parser.add_argument("--measure-scenes", type=int, default=2)
    parser.add_argument("--devkit-every", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(*args.child)
        return
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes, args.measure_scenes, args.devkit_every))


if __name__ == "__main__":
    main()
