"""Row 4: every box of every keyframe camera frame of the trainval-scale dataset projected: boxes per second.

    .venv/bin/python benchmarks/bench_project_all.py [--repeats 3] [--scenes-per-batch 100]

A fresh process per repeat; timed in it after the imports: for each batch of `--scenes-per-batch` scenes,
the batch's keyframe camera frames (6 cameras), annotations and samples are read with one `pl.collect_all`
(row groups pruned by scene_name statistics) and `project_boxes(..., visibility="none")` projects every
(frame, box) pair: corners in camera and pixels, depths, per-corner visibility, the ANY flag. Batches bound
the memory (one call over all ~7M pairs would hold ~4 GB of arrays). Reported: (frame, box) pairs per second
(the work done), and how many of them are visible (ANY); whole-process wall time and peak RSS alongside.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

SCENES_PER_BATCH = 100


def child(out: str, scenes_per_batch: int) -> None:
    start = time.perf_counter()
    import polars as pl

    import nuparquet
    from nuparquet.projection.boxes import project_boxes

    import_s = time.perf_counter() - start
    start = time.perf_counter()
    ds = nuparquet.open(out)
    scene_names = ds.scan("scenes").select("name").sort("name").collect()["name"].to_list()
    frames_n = pairs = visible = 0
    read_s = project_s = 0.0
    for first in range(0, len(scene_names), scenes_per_batch):
        batch_start = time.perf_counter()
        batch = scene_names[first:first + scenes_per_batch]
        in_batch = pl.col("scene_name").is_in(batch)
        frames = ds.scan("frames").filter(in_batch, pl.col("modality").cast(pl.String) == "camera",
                                          pl.col("is_key_frame"))
        annotations = ds.scan("annotations").filter(in_batch)
        samples = ds.scan("tables/sample").join(frames.select("scene_token").unique(), on="scene_token", how="semi")
        frames, annotations, samples = pl.collect_all([frames, annotations, samples])
        read_end = time.perf_counter()
        projected = project_boxes(frames, annotations, samples, visibility="none")
        project_s += time.perf_counter() - read_end
        read_s += read_end - batch_start
        frames_n += frames.height
        pairs += len(projected)
        visible += int(projected.visible.sum())
        del projected
    total_s = time.perf_counter() - start
    print(json.dumps({"import_s": import_s, "total_s": total_s, "read_s": read_s, "project_s": project_s,
                      "frames": frames_n, "pairs": pairs, "visible": visible, "scenes": len(scene_names),
                      "pairs_per_s": pairs / total_s, "visible_per_s": visible / total_s}))


def run(repeats: int = 3, scenes_per_batch: int = SCENES_PER_BATCH) -> dict:
    import bench_data as datasets
    from harness import Row, log, megabytes, python_child, repeat, seconds, summarize

    out = datasets.trainval_out()
    log("row 4: project every keyframe camera frame's boxes")
    cmd = python_child(__file__, "--child", out, "--scenes-per-batch", scenes_per_batch)
    ours = summarize(repeat(cmd, repeats, label="nuparquet project all"), total_s="total_s", read_s="read_s",
                     project_s="project_s", frames="frames", pairs="pairs", visible="visible",
                     pairs_per_s="pairs_per_s", visible_per_s="visible_per_s")
    row = Row(
        id="4",
        benchmark=f"project all boxes of all keyframe camera frames, {scenes_per_batch} scenes per call "
        f"({ours['frames']:,.0f} frames, "
        f"{ours['pairs']:,.0f} (frame, box) pairs, {ours['visible']:,.0f} visible)",
        ours=f"{ours['pairs_per_s'] / 1e6:.2f} M boxes/s ({seconds(ours['total_s'])}: read {seconds(ours['read_s'])}"
        f" + project {seconds(ours['project_s'])}; process {seconds(ours['wall_s'])}, "
        f"{megabytes(ours['max_rss_mb'])} peak)",
        reference="—",
        ratio="—",
        target="report boxes/s",
        met=None,
    )
    return {"name": "project_all", "command": " ".join(map(str, cmd)), "nuparquet": ours, "rows": [row]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scenes-per-batch", type=int, default=SCENES_PER_BATCH)
    parser.add_argument("--child", metavar="OUT", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.scenes_per_batch)
        return
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes_per_batch))


if __name__ == "__main__":
    main()
