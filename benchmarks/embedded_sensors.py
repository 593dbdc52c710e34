"""Embedded-sensor row: training samples read from the sensor files embedded in the output (`convert --embed
camera,lidar,radar`, no dataroot) against the same samples read from the local files, in one run.

    PYTHONPATH=. .venv/bin/python benchmarks/embedded_sensors.py [--repeats 5] [--sweeps 0]

Data: the real two-scene extract (`../shared/data/nuscenes-extract`), converted twice into the bench cache: with
`--embed camera,lidar,radar` (opened with a dataroot that does not exist, so every byte comes from
`sensor_files/`) and without (opened on the extract: every byte from the files). Both are read through the same
`nuparquet.training.Samples(ds, "val", version="v1.0-mini", sweeps=N)`: per sample the six camera JPEGs decoded,
LIDAR_TOP and N sweeps aggregated (the extract holds keyframe files only: N = 0), the boxes, so what differs is
only where the bytes come from. The files stay
in the page cache (a warm-up epoch for each side first); the two sides alternate, `--repeats` epochs each, in
this process; the figure is the median samples/s. Also timed: the bytes alone (`ds.sensors.file_bytes` of every
keyframe camera and lidar file of the epoch), embedded vs file.

Prints the row (target: embedded >= 0.9x the files) and writes benchmarks/results/<UTC time>-embedded_sensors.json.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path
from statistics import median

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_data import CACHE as BENCH_CACHE  # noqa: E402
from harness import REPO, log, machine  # noqa: E402

EXTRACT = REPO.parent / "shared" / "data" / "nuscenes-extract"
VERSION = "v1.0-mini-extract"
CACHE = BENCH_CACHE / "embedded_sensors"


def prepare() -> tuple[Path, Path]:
    """(embedded output, plain output) of the extract, converted once into the cache."""
    from nuparquet.conversion import convert

    outs = {}
    for name, options in (("embedded", {"embed": ("camera", "lidar", "radar")}), ("plain", {})):
        out = CACHE / name
        if not (out / "manifest.json").is_file():
            shutil.rmtree(out, ignore_errors=True)
            log(f"converting {EXTRACT} into {out} {options}")
            convert(EXTRACT, VERSION, out, **options)
        outs[name] = out
    return outs["embedded"], outs["plain"]


def epoch(samples) -> float:
    """Seconds to read every sample once."""
    start = time.perf_counter()
    for i in range(len(samples)):
        samples[i]
    return time.perf_counter() - start


def bytes_epoch(ds, files: list[tuple[str, str, str]]) -> float:
    start = time.perf_counter()
    for token, filename, modality in files:
        ds.sensors.file_bytes(token, filename, modality)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--sweeps", type=int, default=0)
    args = parser.parse_args()

    import os

    import nuparquet
    from nuparquet.training import Samples

    embedded_out, plain_out = prepare()
    embedded = nuparquet.open(embedded_out, dataroot=CACHE / "no-dataroot")  # never there: bytes from the output
    plain = nuparquet.open(plain_out, dataroot=EXTRACT)
    sides = {"embedded": Samples(embedded, "val", version="v1.0-mini", sweeps=args.sweeps),
             "files": Samples(plain, "val", version="v1.0-mini", sweeps=args.sweeps)}
    s = sides["files"]
    files = [(t.decode(), f.decode(), "camera") for i in s.indices for t, f in zip(s._cam_token[i], s._cam_file[i])]
    files += [(s._lidar_token[i].decode(), s._lidar_file[i].decode(), "lidar") for i in s.indices]
    for side in sides.values():
        epoch(side)  # warm: page cache, footers, the embedded index
    times: dict[str, list[float]] = {"embedded": [], "files": []}
    byte_times: dict[str, list[float]] = {"embedded": [], "files": []}
    for r in range(args.repeats):
        for name in ("embedded", "files") if r % 2 == 0 else ("files", "embedded"):
            times[name].append(epoch(sides[name]))
            byte_times[name].append(bytes_epoch(embedded if name == "embedded" else plain, files))
            log(f"  {name} [{r + 1}/{args.repeats}] {times[name][-1]:.2f} s epoch, {byte_times[name][-1]:.3f} s bytes")
    n = len(sides["files"])
    rate = {name: n / median(t) for name, t in times.items()}
    byte_rate = {name: len(files) / median(t) for name, t in byte_times.items()}
    result = {
        "benchmark": "embedded_sensors", "samples": n, "sweeps": args.sweeps, "repeats": args.repeats,
        "samples_per_s": rate, "ratio": rate["embedded"] / rate["files"],
        "files_per_s": byte_rate, "bytes_ratio": byte_rate["embedded"] / byte_rate["files"],
        "epoch_s": times, "bytes_s": byte_times, "load": os.getloadavg(), "machine": machine(),
        "command": "benchmarks/embedded_sensors.py " + " ".join(sys.argv[1:]),
    }
    print(f"embedded sensors: Samples epoch ({n} samples, 6 cameras + LIDAR_TOP + {args.sweeps} sweeps): "
          f"{rate['embedded']:.2f} samples/s embedded vs {rate['files']:.2f} from files = "
          f"{result['ratio']:.2f}x (target >= 0.9x); bytes alone ({len(files)} files): "
          f"{byte_rate['embedded']:.0f} vs {byte_rate['files']:.0f} files/s = {result['bytes_ratio']:.2f}x")
    results = REPO / "benchmarks" / "results"
    results.mkdir(exist_ok=True)
    stamp = time.strftime("%Y-%m-%dT%H%M%SZ", time.gmtime())
    (results / f"{stamp}-embedded_sensors.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
