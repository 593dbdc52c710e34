"""The demo pipeline (`make demo`): the whole job on a small synthetic nuScenes-format dataset.

synthesise (with camera images, lidar and map expansion) -> validate -> convert -> info -> stats (+ plots) ->
render a CAM_FRONT video, a 6-camera mosaic, a bird's-eye view and the six cameras with the bird's-eye view ->
export the first scene as an MCAP file for Foxglove -> write the dataset's web report (open report/index.html).
Every step is a public `nuparquet` command, exactly as a user would type it; the outputs land in --out (default
demo-out/).
"""

from __future__ import annotations

import argparse
import shlex
import shutil
import sys
import time
from pathlib import Path

from nuparquet import open as nuparquet_open
from nuparquet.cli.main import main as nuparquet

VERSION = "v1.0-demo"


def step(*argv: str) -> None:
    print(f"\n$ nuparquet {shlex.join(argv)}", flush=True)
    start = time.perf_counter()
    code = nuparquet(list(argv))
    if code != 0:
        sys.exit(f"demo step failed with exit code {code}: nuparquet {shlex.join(argv)}")
    print(f"  ({time.perf_counter() - start:.1f} s)", flush=True)


def run(out: Path, scenes: int, samples: int) -> None:
    if out.exists():
        shutil.rmtree(out)
    data, converted = out / "data", out / "dataset"
    step("synth", str(data), "--scenes", str(scenes), "--samples-per-scene", str(samples), "--with-images",
         "--with-lidar", "--seed", "0", "--version", VERSION)
    step("validate", str(data), "--version", VERSION)
    step("convert", str(data), "--version", VERSION, "--out", str(converted))
    step("info", str(converted))
    step("stats", str(converted), "--plots", str(out / "plots"))
    step("sql", str(converted), "SELECT category_name, count(*) AS boxes FROM annotations "
         "GROUP BY category_name ORDER BY boxes DESC LIMIT 5")
    scene = nuparquet_open(converted).scan("scenes").select("name").sort("name").first().collect().item()
    step("render", str(converted), "--scene", scene, "--channel", "CAM_FRONT", "--out", str(out / f"{scene}-CAM_FRONT.mp4"))
    step("render", str(converted), "--scene", scene, "--channel", "all", "--out", str(out / f"{scene}-mosaic.mp4"))
    step("render", str(converted), "--scene", scene, "--channel", "bev", "--out", str(out / f"{scene}-bev.mp4"))
    step("render", str(converted), "--scene", scene, "--channel", "all", "--bev",
         "--out", str(out / f"{scene}-mosaic-bev.mp4"))
    step("export-mcap", str(converted), "--scene", scene, "--out", str(out / f"{scene}.mcap"))
    step("report", str(converted), "--out", str(out / "report"))
    print(f"\ndemo outputs in {out}/: plots/, {scene}-CAM_FRONT.mp4, {scene}-mosaic.mp4, {scene}-bev.mp4, "
          f"{scene}-mosaic-bev.mp4, {scene}.mcap (open in Foxglove), report/index.html (open in a browser)")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("demo-out"), help="output folder (replaced)")
    parser.add_argument("--scenes", type=int, default=2)
    parser.add_argument("--samples-per-scene", type=int, default=10)
    args = parser.parse_args()
    run(args.out, args.scenes, args.samples_per_scene)
