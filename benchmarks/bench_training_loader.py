"""Rows 16a-16c: the training loader (`nuparquet.training.Samples`) against mmdetection3d's loading pipeline
restated over the same samples, and the memory of a data-loader worker against one holding the devkit's `NuScenes`.

    .venv/bin/python benchmarks/bench_training_loader.py [--scenes 6] [--samples-per-scene 20] [--repeats 1]

Data: a cached synthetic set with 1600x900 camera JPEGs and lidar/radar files for every keyframe and sweep
(`.bench-cache/training/`, `synthesize(with_images=True, with_lidar=True)`), converted, and its v2 infos
(`nuparquet index`, 10 sweeps). Every loader serves the same split's samples, each the six images decoded
(cv2, BGR), the keyframe lidar with up to 10 sweeps aggregated as `LoadPointsFromMultiSweeps(10)`, and the boxes:

- ours: `Samples(OUT, split, sweeps=10)` built in the parent (its construction timed apart), pickled to the workers;
- mmdet3d: the infos pickle loaded in the parent and sent to the workers (mmdetection3d's dataset holds its
  `data_list` in every worker), then per sample `LoadMultiViewImageFromFiles` (file bytes, `cv2.imdecode`: mmcv's
  cv2 backend), `LoadPointsFromFile(load_dim=5)`, `LoadPointsFromMultiSweeps(sweeps_num=10)` and
  `LoadAnnotations3D` restated in numpy/cv2 below;
- devkit: the same mmdet3d pipeline in a worker that holds the devkit's `NuScenes(version, dataroot)` (built in
  the worker, as a devkit-based dataset's workers each hold one).

Each configuration runs in a fresh process (`--child`): it starts 1 or 2 workers with multiprocessing's spawn (no
torch), each worker takes every n-th sample (a DataLoader's split of a map-style dataset), and reports its count,
the points it produced (checked equal between ours and mmdet3d) and its peak RSS (`VmHWM` of /proc/self/status:
`ru_maxrss` would carry the parent's high-water mark across exec). samples/s = samples / the epoch's wall time,
worker start-up included; "steady" leaves out each worker's start-up (spawn, imports, open, first item), what a
long epoch or `persistent_workers=True` sees.

Row 16c: one worker's peak memory on the 100-scene metadata-only set (`bench_data.scenes_out(100)`, 4,000 samples,
no sensor files): ours unpickles a boxes-only `Samples` of the split and reads 200 items; the reference builds the
devkit's `NuScenes` in the worker and reads the same number of samples' boxes (`get_boxes`). Both grow with the
dataset: this is the metadata each worker holds, the sensor pipeline of rows 16a-b comes on top of either.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

SPLIT = "train"
VERSION = "v1.0-trainval"
SWEEPS = 10
LOADERS = ("ours", "mmdet3d", "devkit")
META_SCENES = 100  # the metadata-only set of row 16c (bench_data.scenes_out)
META_SAMPLES = 200  # samples each row 16c worker reads (boxes only)
TARGET_SPEED = 1.5
TARGET_MEMORY = 0.25


# --- the data ----------------------------------------------------------------------------------------------------

def dataset(scenes: int, samples_per_scene: int) -> tuple[Path, Path, Path]:
    """(dataroot, OUT, infos pickle), built once and cached with their parameters."""
    import bench_data
    from harness import log

    root = bench_data.CACHE / f"training-{scenes}x{samples_per_scene}"
    params = {"scenes": scenes, "samples_per_scene": samples_per_scene, "seed": 0, "version": VERSION,
              "schemas": bench_data._schemas_digest()}
    marker = root / bench_data.PARAMS
    data, out, infos = root / "data", root / "out", root / "infos" / f"nuscenes_infos_{SPLIT}.pkl"
    if not (marker.is_file() and json.loads(marker.read_text()) == params and infos.is_file()):
        import shutil

        from nuparquet import convert
        from nuparquet.index import IndexOptions, build_index
        from nuparquet.synth import synthesize

        shutil.rmtree(root, ignore_errors=True)
        log(f"building {root} ({scenes} scenes x {samples_per_scene} samples, images and lidar) ...")
        synthesize(data, scenes=scenes, samples_per_scene=samples_per_scene, with_images=True, with_lidar=True,
                   seed=0, version=VERSION)
        convert(data, VERSION, out, workers=1)
        build_index(out, str(infos.parent), IndexOptions(version=VERSION, max_sweeps=SWEEPS, parquet=False))
        marker.write_text(json.dumps(params) + "\n")
    return data, out, infos


# --- mmdetection3d v1.4.0's pipeline, restated over numpy and cv2 ------------------------------------------------

def _remove_close(points, radius=1.0):  # LoadPointsFromMultiSweeps._remove_close
    import numpy as np

    x_filt = np.abs(points[:, 0]) < radius
    y_filt = np.abs(points[:, 1]) < radius
    not_close = np.logical_not(np.logical_and(x_filt, y_filt))
    return points[not_close]


def mmdet3d_pipeline(entry: dict, root: Path) -> dict:
    """Det3DDataset.parse_data_info's paths, then LoadMultiViewImageFromFiles, LoadPointsFromFile(load_dim=5),
    LoadPointsFromMultiSweeps(sweeps_num=10, remove_close=True, pad_empty_sweeps=True, test_mode=True),
    LoadAnnotations3D (boxes and labels)."""
    import cv2
    import numpy as np

    results = {"timestamp": entry["timestamp"]}
    images = []
    for channel, cam in entry["images"].items():  # mmcv.imfrombytes(get(path), backend="cv2")
        content = (root / "samples" / channel / cam["img_path"]).read_bytes()
        images.append(cv2.imdecode(np.frombuffer(content, np.uint8), cv2.IMREAD_COLOR))
    img = np.stack(images, axis=-1)
    results["img"] = [img[..., i] for i in range(img.shape[-1])]
    points = np.fromfile(root / "samples" / "LIDAR_TOP" / entry["lidar_points"]["lidar_path"], dtype=np.float32)
    points = points.reshape(-1, 5)
    points[:, 4] = 0
    sweep_points_list = [points]
    ts = results["timestamp"]
    sweeps = entry.get("lidar_sweeps")
    if sweeps is None:
        for _ in range(SWEEPS):
            sweep_points_list.append(_remove_close(points))
    else:
        for sweep in sweeps[:SWEEPS]:
            path = root / os.path.relpath(sweep["lidar_points"]["lidar_path"], "./data/nuscenes")
            points_sweep = np.copy(np.fromfile(path, dtype=np.float32)).reshape(-1, 5)
            points_sweep = _remove_close(points_sweep)
            lidar2sensor = np.array(sweep["lidar_points"]["lidar2sensor"])
            points_sweep[:, :3] = points_sweep[:, :3] @ lidar2sensor[:3, :3]
            points_sweep[:, :3] -= lidar2sensor[:3, 3]
            points_sweep[:, 4] = ts - sweep["timestamp"]
            sweep_points_list.append(points_sweep)
    results["points"] = np.concatenate(sweep_points_list)[:, [0, 1, 2, 3, 4]]
    instances = entry.get("instances", [])
    boxes = np.array([a["bbox_3d"] for a in instances], dtype=np.float32).reshape(-1, 7)
    velocity = np.array([a["velocity"] for a in instances], dtype=np.float32).reshape(-1, 2)
    boxes = np.concatenate([boxes, np.nan_to_num(velocity)], axis=1)
    boxes[:, 2] -= boxes[:, 5] / 2  # LiDARInstance3DBoxes(origin=(0.5, 0.5, 0.5))
    results["gt_bboxes_3d"] = boxes
    results["gt_labels_3d"] = np.array([a["bbox_label_3d"] for a in instances], dtype=np.int64)
    return results


class DevkitBoxes:
    """A worker holding the devkit's `NuScenes` (built in the worker) and reading each sample's boxes through it."""

    def __init__(self, root: Path) -> None:
        self.root, self.nusc = root, None

    def open(self) -> None:
        from nuscenes.nuscenes import NuScenes

        self.nusc = NuScenes(VERSION, str(self.root), verbose=False)

    def __len__(self) -> int:
        return META_SAMPLES

    def __getitem__(self, i: int) -> dict:
        sample = self.nusc.sample[i]
        return {"boxes": self.nusc.get_boxes(sample["data"]["LIDAR_TOP"])}


class Mmdet3dLoader:
    """A map-style dataset over the infos' `data_list` (held whole, as mmdetection3d's dataset holds it)."""

    def __init__(self, infos: Path, root: Path, devkit_version: str | None = None) -> None:
        self.data_list = pickle.loads(infos.read_bytes())["data_list"]
        self.root, self.devkit_version = root, devkit_version
        self.nusc = None

    def open(self) -> None:
        if self.devkit_version:  # the devkit-based dataset's worker: its own NuScenes
            from nuscenes.nuscenes import NuScenes

            self.nusc = NuScenes(self.devkit_version, str(self.root), verbose=False)

    def __len__(self) -> int:
        return len(self.data_list)

    def __getitem__(self, i: int) -> dict:
        return mmdet3d_pipeline(self.data_list[i], self.root)


# --- workers --------------------------------------------------------------------------------------------------

def _vm_hwm_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def worker(loader, worker_id: int, num_workers: int, limit: int, queue) -> None:
    start = time.perf_counter()
    if hasattr(loader, "open"):
        loader.open()
    count, points, first_s = 0, 0, None
    for i in range(worker_id, min(len(loader), limit), num_workers):
        item = loader[i]
        count += 1
        points += len(item.get("points", ()))
        if first_s is None:
            first_s = time.perf_counter() - start
            steady = time.perf_counter()
    steady_s = time.perf_counter() - steady if count > 1 else float("nan")
    queue.put({"worker": worker_id, "samples": count, "points": points, "first_s": first_s, "steady_s": steady_s,
               "peak_rss_mb": _vm_hwm_mb()})


def child(kind: str, workers: int, root: str, out: str, infos: str) -> None:
    import multiprocessing

    start = time.perf_counter()
    limit = META_SAMPLES if kind.endswith("-meta") else 1 << 62
    if kind == "ours":
        from nuparquet.training import Samples

        loader = Samples(out, SPLIT, sweeps=SWEEPS, version=VERSION)
    elif kind == "ours-meta":  # boxes only: the metadata set has no sensor files
        from nuparquet.training import Samples

        loader = Samples(out, SPLIT, lidar=False, cameras=(), sweeps=SWEEPS, version=VERSION)
    elif kind == "devkit-meta":
        loader = DevkitBoxes(Path(root))
    else:
        loader = Mmdet3dLoader(Path(infos), Path(root), VERSION if kind == "devkit" else None)
    build_s = time.perf_counter() - start
    context = multiprocessing.get_context("spawn")
    queue = context.Queue()
    start = time.perf_counter()
    procs = [context.Process(target=worker, args=(loader, w, workers, limit, queue)) for w in range(workers)]
    for p in procs:
        p.start()
    reports = [queue.get() for _ in procs]
    for p in procs:
        p.join()
    epoch_s = time.perf_counter() - start
    samples = sum(r["samples"] for r in reports)
    steady = sum(r["samples"] - 1 for r in reports) / max(r["steady_s"] for r in reports)
    samples_in_loader = len(loader)
    print(json.dumps({"build_s": build_s, "epoch_s": epoch_s, "samples": samples, "samples_per_s": samples / epoch_s,
                      "steady_samples_per_s": steady, "points": sum(r["points"] for r in reports),
                      "worker_peak_rss_mb": max(r["peak_rss_mb"] for r in reports),
                      "first_item_s": max(r["first_s"] for r in reports), "pickle_bytes": len(pickle.dumps(loader)),
                      "loader_samples": samples_in_loader}))


# --- the row ----------------------------------------------------------------------------------------------------

def run(scenes: int = 6, samples_per_scene: int = 20, repeats: int = 1) -> dict:
    from harness import Row, load_average, log, megabytes, python_child, repeat, summarize

    root, out, infos = dataset(scenes, samples_per_scene)
    log(f"row 16: training loader over {root}")
    figures, commands = {}, {}
    for workers in (1, 2):
        for kind in LOADERS:
            cmd = python_child(__file__, "--child", kind, workers, root, out, infos)
            label = f"{kind}, {workers} worker{'s' if workers > 1 else ''}"
            figures[label] = summarize(repeat(cmd, repeats, label=label), build_s="build_s", epoch_s="epoch_s",
                                       samples="samples", samples_per_s="samples_per_s",
                                       steady_samples_per_s="steady_samples_per_s", points="points",
                                       worker_peak_rss_mb="worker_peak_rss_mb", first_item_s="first_item_s",
                                       pickle_bytes="pickle_bytes")
            commands[label] = " ".join(map(str, cmd))
    same = all(figures[f"ours, {w} worker{'s' if w > 1 else ''}"]["points"]
               == figures[f"mmdet3d, {w} worker{'s' if w > 1 else ''}"]["points"] for w in (1, 2))
    rows = []
    for workers in (1, 2):
        suffix = f"{workers} worker{'s' if workers > 1 else ''}"
        ours, ref, dev = (figures[f"{k}, {suffix}"] for k in LOADERS)
        speed = ours["samples_per_s"] / ref["samples_per_s"]
        memory = ours["worker_peak_rss_mb"] / dev["worker_peak_rss_mb"]
        rows.append(Row(
            id=f"16{'ab'[workers - 1]}",
            benchmark=f"training loader, {ours['samples']:.0f} samples (6 images 1600x900, lidar + {SWEEPS} sweeps, "
            f"boxes), {suffix}, spawn",
            ours=f"{ours['samples_per_s']:.2f} samples/s (steady {ours['steady_samples_per_s']:.2f}; built in "
            f"{ours['build_s']:.2f} s, pickle {ours['pickle_bytes'] / 1024:.0f} kB); worker peak "
            f"{megabytes(ours['worker_peak_rss_mb'])}",
            reference=f"mmdet3d restated {ref['samples_per_s']:.2f} samples/s (steady "
            f"{ref['steady_samples_per_s']:.2f}), worker {megabytes(ref['worker_peak_rss_mb'])}; devkit-holding "
            f"worker {megabytes(dev['worker_peak_rss_mb'])} ({dev['samples_per_s']:.2f} samples/s)",
            ratio=f"{speed:.2f}x speed; {memory:.2f} of the devkit worker's memory",
            target=f">= {TARGET_SPEED}x, <= {TARGET_MEMORY} of the memory",
            met=same and speed >= TARGET_SPEED and memory <= TARGET_MEMORY,
        ))
    import bench_data

    meta_root, meta_out = bench_data.scenes_root(META_SCENES), bench_data.scenes_out(META_SCENES)
    for kind in ("ours-meta", "devkit-meta"):
        cmd = python_child(__file__, "--child", kind, 1, meta_root, meta_out, "-")
        figures[kind] = summarize(repeat(cmd, repeats, label=kind), build_s="build_s", samples="samples",
                                  worker_peak_rss_mb="worker_peak_rss_mb", pickle_bytes="pickle_bytes",
                                  loader_samples="loader_samples", first_item_s="first_item_s")
        commands[kind] = " ".join(map(str, cmd))
    ours, dev = figures["ours-meta"], figures["devkit-meta"]
    memory = ours["worker_peak_rss_mb"] / dev["worker_peak_rss_mb"]
    rows.append(Row(
        id="16c",
        benchmark=f"one data-loader worker's peak memory, {META_SCENES}-scene metadata set (split {SPLIT}: "
        f"{ours['loader_samples']:.0f} samples; {META_SAMPLES} samples' boxes read)",
        ours=f"{megabytes(ours['worker_peak_rss_mb'])} (the `Samples` pickle {ours['pickle_bytes'] / 2**20:.1f} MB, "
        f"built in {ours['build_s']:.1f} s in the parent)",
        reference=f"a worker holding the devkit's `NuScenes`: {megabytes(dev['worker_peak_rss_mb'])} (built in the "
        f"worker: first item after {dev['first_item_s']:.1f} s)",
        ratio=f"{memory:.2f} of the memory",
        target=f"<= {TARGET_MEMORY} of the memory",
        met=memory <= TARGET_MEMORY,
    ))
    return {"name": "training_loader", "figures": figures, "commands": commands, "same_points": same,
            "load": load_average(), "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=6)
    parser.add_argument("--samples-per-scene", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--child", nargs=5, metavar=("KIND", "WORKERS", "ROOT", "OUT", "INFOS"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        kind, workers, root, out, infos = args.child
        child(kind, int(workers), root, out, infos)
        return
    from harness import report_alone

    report_alone(run(args.scenes, args.samples_per_scene, args.repeats))


if __name__ == "__main__":
    main()
