"""Row 12: `nuparquet.devkit.NuScenes` against nuscenes-devkit's `NuScenes`, on the trainval-scale synthetic set.

    .venv/bin/python benchmarks/bench_devkit_compat.py [--scenes 850] [--repeats 3] [--devkit-repeats 1]
        [--client eval,infos] [--samples N]

Every figure comes from a fresh child process per repeat (harness.run_child: wall time, peak RSS), for each object:
- 12a construction: `NuScenes(version, dataroot[, parquet=OUT])`, timed in the process (`construct_s`), then the
  small tables touched (`scene[0]`, `log[0]`, `visibility[0]`); the process's peak RSS is the "until a large table
  is touched" memory. Targets: ≥ 100× faster, ≤ 1/20 of the devkit's peak.
- 12b a real client end to end (the whole process: interpreter, imports, construction, client; the construction
  figure includes importing the object's module when the client did not import it first): `eval`, the devkit's
  detection-evaluation
  loaders `load_gt` + `add_center_dist` + `filter_eval_boxes` for the train and val splits (every annotation of
  those scenes: its record, velocity, attributes); `infos`, mmdetection3d's info converter loop
  (`tests/parity/mmdet3d_converter.py`, a faithful re-statement of v1.4.0's `_fill_trainval_infos`; the first
  `--samples` samples, default all: at trainval scale the devkit's loop takes tens of minutes), also with
  `NuScenes(..., keep_records=False)` (no record kept). The children print a digest of their output; it must be
  equal. Targets: ≥ 3× faster, ≤ half the peak RSS, identical output.
- 12c `get()` per call once the table is loaded: in the `eval` children, 200,000 lookups of sample_annotation
  tokens already looked up once, against a plain dict lookup of the same tokens in the same process. Target:
  within 2× of the devkit's `get`.
`--profile` runs the `infos` and `eval` clients once in this process with cProfile on nuparquet's object and prints
where the time goes.

What bounds 12b: the `eval` loaders spend most of their time in the devkit's own evaluation code (a `DetectionBox`
per annotation, with its checks), identical on both objects, so their end-to-end ratio stays near
(devkit construction + C) / C; the `infos` loop spends it in `get_sample_data` (six cameras and the lidar per
sample), where nuparquet's batch visibility pre-check leaves the devkit's per-box work for the boxes that show.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import sys
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit imports pyplot; never open a window

REPO = Path(__file__).resolve().parent.parent
TARGET_CONSTRUCT_RATIO = 100.0
TARGET_CONSTRUCT_RSS_FRACTION = 1 / 20
TARGET_CLIENT_RATIO = 3.0
TARGET_CLIENT_RSS_FRACTION = 1 / 2
TARGET_GET_RATIO = 2.0
GET_LOOKUPS = 200_000
EVAL_SPLITS = ("train", "val")


def open_nusc(impl: str, root: str, version: str, out: str):
    if impl == "devkit":
        from nuscenes.nuscenes import NuScenes

        return NuScenes(version, dataroot=root, verbose=False)
    from nuparquet.devkit import NuScenes

    return NuScenes(version, dataroot=root, parquet=out, verbose=False, keep_records=impl != "nuparquet-lean")


def construct_child(impl: str, root: str, version: str, out: str) -> None:
    start = time.perf_counter()
    if impl == "devkit":
        import nuscenes.nuscenes  # noqa: F401 - the import is timed apart from the construction
    else:
        import nuparquet.devkit  # noqa: F401
    imported = time.perf_counter()
    nusc = open_nusc(impl, root, version, out)
    constructed = time.perf_counter()
    small = (nusc.scene[0]["name"], nusc.log[0]["location"], nusc.visibility[0]["level"])
    print(json.dumps({"import_s": imported - start, "construct_s": constructed - imported,
                      "small_tables_s": time.perf_counter() - constructed, "small": small}))
    os._exit(0)  # neither side pays for freeing its objects


def client_child(impl: str, client: str, root: str, version: str, out: str, samples: int) -> None:
    start = time.perf_counter()
    import_client(client)  # the client's own imports (the devkit's evaluation imports matplotlib, scipy, ...)
    imported = time.perf_counter()
    nusc = open_nusc(impl, root, version, out)
    constructed = time.perf_counter()
    if client == "eval":
        output = run_eval_client(nusc)
    else:
        output = run_infos_client(nusc, samples)
    done = time.perf_counter()
    report = {"import_s": imported - start, "construct_s": constructed - imported, "client_s": done - constructed,
              "digest": digest(output)}
    if client == "eval":
        report |= time_gets(nusc)
    print(json.dumps(report))
    os._exit(0)


def import_client(client: str) -> None:
    if client == "eval":
        import nuscenes.eval.common.loaders  # noqa: F401
        import nuscenes.eval.detection.config  # noqa: F401
    else:
        sys.path.insert(0, str(REPO / "tests" / "parity"))
        import mmdet3d_converter  # noqa: F401


def run_eval_client(nusc) -> list:
    from nuscenes.eval.common.loaders import add_center_dist, filter_eval_boxes, load_gt
    from nuscenes.eval.detection.config import config_factory
    from nuscenes.eval.detection.data_classes import DetectionBox

    class_range = config_factory("detection_cvpr_2019").class_range
    output = []
    for split in EVAL_SPLITS:
        boxes = add_center_dist(nusc, load_gt(nusc, split, DetectionBox))
        output.append(filter_eval_boxes(nusc, boxes, class_range).serialize())
    return output


def run_infos_client(nusc, samples: int) -> list:
    sys.path.insert(0, str(REPO / "tests" / "parity"))
    from mmdet3d_converter import fill_trainval_infos

    from nuparquet.devkit.utils import splits  # the same scene lists as the devkit's (tested)

    train = {s["token"] for s in nusc.scene if s["name"] in set(splits.train)}
    val = {s["token"] for s in nusc.scene if s["name"] in set(splits.val)}
    chosen = None if samples <= 0 else nusc.sample[:samples]
    return list(fill_trainval_infos(nusc, train, val, check_files=False, samples=chosen))


def time_gets(nusc) -> dict:
    """ns per `nusc.get("sample_annotation", token)` of tokens already looked up once, and per plain dict lookup."""
    table = nusc.sample_annotation
    rng = random.Random(0)
    tokens = [table[rng.randrange(len(table))]["token"] for _ in range(GET_LOOKUPS)]
    for token in tokens:
        nusc.get("sample_annotation", token)
    get = nusc.get
    start = time.perf_counter()
    for token in tokens:
        get("sample_annotation", token)
    get_s = time.perf_counter() - start
    plain = {token: nusc.get("sample_annotation", token) for token in tokens}
    start = time.perf_counter()
    for token in tokens:
        plain[token]
    dict_s = time.perf_counter() - start
    return {"get_ns": get_s / len(tokens) * 1e9, "dict_ns": dict_s / len(tokens) * 1e9}


def digest(value) -> str:
    """A digest of a client's output that two objects agree on exactly when their outputs are equal (types, key
    and list order, float bits), fed leaf by leaf: no copy of the output is built."""
    import numpy as np

    hasher = hashlib.sha256()
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, np.ndarray):
            hasher.update(f"ndarray {item.dtype} {item.shape}:".encode())
            hasher.update(np.ascontiguousarray(item).tobytes() if item.dtype != object else repr(item.tolist()).encode())
        elif isinstance(item, dict):
            hasher.update(f"dict {len(item)}:".encode())
            for key, child in reversed(list(item.items())):
                stack.append(child)
                stack.append(key)
        elif isinstance(item, (list, tuple)):
            hasher.update(f"{type(item).__name__} {len(item)}:".encode())
            stack.extend(reversed(item))
        elif isinstance(item, (float, np.floating)):
            hasher.update(f"{type(item).__name__} {float(item).hex()};".encode())
        elif isinstance(item, (bool, int, str, np.integer, np.bool_)) or item is None:
            hasher.update(f"{type(item).__name__} {item!r};".encode())
        else:
            raise TypeError(f"cannot digest {type(item).__name__}")
    return hasher.hexdigest()


def profile(root: str, version: str, out: str, samples: int) -> None:
    import cProfile
    import pstats

    nusc = open_nusc("nuparquet", root, version, out)
    for client in ("infos", "eval"):
        profiler = cProfile.Profile()
        profiler.enable()
        run_infos_client(nusc, samples) if client == "infos" else run_eval_client(nusc)
        profiler.disable()
        print(f"--- {client} ---")
        pstats.Stats(profiler).sort_stats("tottime").print_stats(15)


def run(scenes: int = 850, repeats: int = 3, devkit_repeats: int = 1, clients=("eval", "infos"),
        samples: int = 0) -> dict:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_data as datasets
    from harness import Row, log, megabytes, python_child, repeat, seconds, summarize, times

    root, out = datasets.scenes_root(scenes), datasets.scenes_out(scenes)
    version = datasets.TRAINVAL_VERSION
    figures: dict = {"name": "devkit_compat", "scenes": scenes, "commands": {}, "rows": []}

    log("row 12a: construction")
    construct = {}
    for impl, times_run in (("nuparquet", repeats), ("devkit", devkit_repeats)):
        cmd = python_child(__file__, "--construct-child", impl, root, version, out)
        figures["commands"][f"construct {impl}"] = " ".join(map(str, cmd))
        construct[impl] = summarize(repeat(cmd, times_run, label=f"{impl} NuScenes(...)"), construct_s="construct_s",
                                    import_s="import_s")
    ours, theirs = construct["nuparquet"], construct["devkit"]
    speed = theirs["construct_s"] / ours["construct_s"]
    memory = ours["max_rss_mb"] / theirs["max_rss_mb"]
    figures["construct"] = construct
    figures["rows"].append(Row(
        id="12a", benchmark=f"`NuScenes(...)` construction ({scenes} scenes), then the small tables touched",
        ours=f"{seconds(ours['construct_s'])} in-process, {megabytes(ours['max_rss_mb'])} peak (process "
             f"{seconds(ours['wall_s'])})",
        reference=f"devkit {seconds(theirs['construct_s'])} in-process, {megabytes(theirs['max_rss_mb'])} peak "
                  f"(process {seconds(theirs['wall_s'])})",
        ratio=f"speed {times(speed)}, peak RSS {times(1 / memory)} smaller",
        target=f"≥ {TARGET_CONSTRUCT_RATIO:.0f}×, ≤ 1/{1 / TARGET_CONSTRUCT_RSS_FRACTION:.0f} of the devkit's peak",
        met=speed >= TARGET_CONSTRUCT_RATIO and memory <= TARGET_CONSTRUCT_RSS_FRACTION))

    for client in clients:
        log(f"row 12b: client {client} end to end")
        result = {}
        impls = (("nuparquet", repeats), ("nuparquet-lean", repeats), ("devkit", devkit_repeats))
        for impl, times_run in impls if client == "infos" else (impls[0], impls[2]):
            cmd = python_child(__file__, "--client-child", impl, client, root, version, out, samples)
            figures["commands"][f"{client} {impl}"] = " ".join(map(str, cmd))
            runs = repeat(cmd, times_run, label=f"{impl} {client}")
            result[impl] = summarize(runs, construct_s="construct_s", client_s="client_s", get_ns="get_ns",
                                     dict_ns="dict_ns")
            result[impl]["digests"] = sorted({r.report["digest"] for r in runs})
        ours, theirs = result["nuparquet"], result["devkit"]
        same = ours["digests"] == theirs["digests"] and len(ours["digests"]) == 1
        speed = theirs["wall_s"] / ours["wall_s"]
        memory = ours["max_rss_mb"] / theirs["max_rss_mb"]
        figures[f"client_{client}"] = result
        what = ("`load_gt` + `add_center_dist` + `filter_eval_boxes`, train and val" if client == "eval" else
                f"mmdetection3d's info converter loop, {'every sample' if samples <= 0 else f'{samples} samples'}")
        figures["rows"].append(Row(
            id="12b", benchmark=f"a real client end to end ({scenes} scenes): {what}",
            ours=f"{seconds(ours['wall_s'])}, {megabytes(ours['max_rss_mb'])} peak (construction "
                 f"{seconds(ours['construct_s'])}, client {seconds(ours['client_s'])})",
            reference=f"devkit {seconds(theirs['wall_s'])}, {megabytes(theirs['max_rss_mb'])} peak (construction "
                      f"{seconds(theirs['construct_s'])}, client {seconds(theirs['client_s'])})",
            ratio=f"speed {times(speed)}, peak RSS {times(1 / memory)} smaller; output identical: {same}",
            target=f"≥ {TARGET_CLIENT_RATIO:.0f}×, ≤ half the peak, identical",
            met=speed >= TARGET_CLIENT_RATIO and memory <= TARGET_CLIENT_RSS_FRACTION and same))
        if client == "infos":
            lean = result["nuparquet-lean"]
            same = lean["digests"] == theirs["digests"] and len(lean["digests"]) == 1
            speed, memory = theirs["wall_s"] / lean["wall_s"], lean["max_rss_mb"] / theirs["max_rss_mb"]
            figures["rows"].append(Row(
                id="12b", benchmark=f"the same with `keep_records=False` (no record kept: a new dict per access)",
                ours=f"{seconds(lean['wall_s'])}, {megabytes(lean['max_rss_mb'])} peak (client "
                     f"{seconds(lean['client_s'])})",
                reference=f"devkit {seconds(theirs['wall_s'])}, {megabytes(theirs['max_rss_mb'])} peak",
                ratio=f"speed {times(speed)}, peak RSS {times(1 / memory)} smaller; output identical: {same}",
                target=f"≥ {TARGET_CLIENT_RATIO:.0f}×, ≤ half the peak, identical",
                met=speed >= TARGET_CLIENT_RATIO and memory <= TARGET_CLIENT_RSS_FRACTION and same))
        if client == "eval":
            ratio = ours["get_ns"] / theirs["get_ns"]
            figures["rows"].append(Row(
                id="12c", benchmark="`get('sample_annotation', token)` per call, table loaded",
                ours=f"{ours['get_ns']:.0f} ns (dict lookup {ours['dict_ns']:.0f} ns)",
                reference=f"devkit {theirs['get_ns']:.0f} ns (dict lookup {theirs['dict_ns']:.0f} ns)",
                ratio=f"{ratio:.2f}× the devkit's get", target=f"≤ {TARGET_GET_RATIO:.0f}× the devkit's get",
                met=ratio <= TARGET_GET_RATIO))
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=850, help="850: the trainval-scale set; fewer: a smaller one")
    parser.add_argument("--repeats", type=int, default=3, help="nuparquet processes per measurement (median)")
    parser.add_argument("--devkit-repeats", type=int, default=1,
                        help="devkit processes per measurement (each ~1 min and ~8 GB at trainval scale)")
    parser.add_argument("--client", default="eval,infos", help="clients to run: eval, infos (comma-separated)")
    parser.add_argument("--samples", type=int, default=0, help="infos client: the first N samples (0: every one)")
    parser.add_argument("--profile", action="store_true", help="profile the clients on nuparquet's object")
    parser.add_argument("--construct-child", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--client-child", nargs=6, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.construct_child:
        construct_child(*args.construct_child)
        return
    if args.client_child:
        impl, client, root, version, out, samples = args.client_child
        client_child(impl, client, root, version, out, int(samples))
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    if args.profile:
        import bench_data as datasets

        profile(str(datasets.scenes_root(args.scenes)), datasets.TRAINVAL_VERSION,
                str(datasets.scenes_out(args.scenes)), args.samples)
        return
    from harness import report_alone

    clients = tuple(c for c in args.client.split(",") if c)
    unknown = [c for c in clients if c not in ("eval", "infos")]
    if unknown:
        parser.error(f"unknown client(s) {', '.join(unknown)}: choose eval, infos")
    report_alone(run(args.scenes, args.repeats, args.devkit_repeats, clients, args.samples))


if __name__ == "__main__":
    main()
