"""The nuscenes-devkit reference of rows 1-3, one fresh process per repeat (the devkit at trainval scale needs
~10 GB and minutes, so one process serves all three rows):

    .venv/bin/python benchmarks/devkit_reference.py DATAROOT VERSION --scene scene-0001 [--check OUT]

In that process, timed with perf_counter and printed as one JSON line:
- `import_s`: `from nuscenes.nuscenes import NuScenes`;
- `construct_s`: `NuScenes(version, dataroot, verbose=False)`;
- `count_s`: annotations per category over every sample_annotation, a Python loop (`collections.Counter`);
- `project_s`: one scene's CAM_FRONT keyframes, for each `get_sample_data(token, box_vis_level=ANY)` (boxes
  moved into the camera frame and filtered by `box_in_image`), then each box's corners
  (`view_points(box.corners(), K, normalize=True)`) and depths: the same output as `project_boxes(...,
  visibility="any")`. Median of 3 loops in the process (the devkit caches nothing between them).
With `--check OUT` (untimed, after everything else): nuparquet's projection of the same frames from OUT is
compared box for box (same frames, same annotation tokens, corners within 1e-6 px, depths within 1e-9 m).

The parent (`measure`) turns one process into the references of rows 1 and 2 by subtracting what the process
did after the construction (row 1: interpreter start-up + import + construction) or after the count (row 2).
The process ends with `os._exit` after printing, so neither reference pays for freeing the devkit's dicts.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from collections import Counter

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit imports pyplot; never open a window

CORNER_TOLERANCE_PX = 1e-6
DEPTH_TOLERANCE_M = 1e-9
PROJECT_LOOPS = 3


def scene_keyframe_tokens(nusc, scene_name: str, channel: str = "CAM_FRONT") -> list[str]:
    """The scene's keyframe sample_data tokens of `channel`, in time order (the devkit way: sample.next)."""
    scene = next(s for s in nusc.scene if s["name"] == scene_name)
    tokens, sample_token = [], scene["first_sample_token"]
    while sample_token:
        sample = nusc.get("sample", sample_token)
        tokens.append(sample["data"][channel])
        sample_token = sample["next"]
    return tokens


def devkit_project(nusc, frame_tokens: list[str]) -> list[tuple[str, str, object, object]]:
    """(frame token, annotation token, corners_px (8, 2), depths (8,)) of every visible box (ANY)."""
    from nuscenes.utils.geometry_utils import BoxVisibility, view_points

    projected = []
    for frame_token in frame_tokens:
        _, boxes, intrinsic = nusc.get_sample_data(frame_token, box_vis_level=BoxVisibility.ANY)
        for box in boxes:
            corners_camera_m = box.corners()  # (3, 8)
            corners_px = view_points(corners_camera_m, intrinsic, normalize=True)[:2].T
            projected.append((frame_token, box.token, corners_px, corners_camera_m[2]))
    return projected


def check_against_nuparquet(projected, out: str, scene_name: str) -> dict:
    """Compare the devkit's boxes with nuparquet's projection of the same scene (see bench_project_scene)."""
    import numpy as np

    from bench_project_scene import project_scene

    ours, _ = project_scene(out, scene_name)
    row_of = {key: row for row, key in enumerate(zip(ours.frame_token.tolist(), ours.annotation_token.tolist()))}
    devkit_keys = [(frame, annotation) for frame, annotation, _, _ in projected]
    same_boxes = set(devkit_keys) == set(row_of) and len(devkit_keys) == len(row_of)
    result = {"devkit_boxes": len(devkit_keys), "nuparquet_boxes": len(ours), "same_boxes": same_boxes}
    if same_boxes and devkit_keys:
        rows = np.array([row_of[key] for key in devkit_keys])
        corners_px = np.stack([p[2] for p in projected])
        depths = np.stack([p[3] for p in projected])
        result["max_corner_error_px"] = float(np.abs(ours.corners_px[rows] - corners_px).max())
        result["max_depth_error_m"] = float(np.abs(ours.depths[rows] - depths).max())
        result["equal"] = (result["max_corner_error_px"] <= CORNER_TOLERANCE_PX
                           and result["max_depth_error_m"] <= DEPTH_TOLERANCE_M)
    else:
        result["equal"] = same_boxes
    return result


# --- parent side --------------------------------------------------------------------------------------------

_MEASURED: dict[tuple, dict] = {}


def measure(dataroot, version: str, scene: str, out, repeats: int) -> dict:
    """Run the devkit reference `repeats` times, each in a fresh process; memoised, so that run_all measures it
    once for rows 1-3. Returns the medians: `load_wall_s` (row 1: process up to the end of construction),
    `count_wall_s` (row 2: up to the end of the count), `max_rss_mb`, `construct_s`, `count_s`, `project_s`,
    the category counts, and the equality check of the projection (from the first run)."""
    from harness import log, median, python_child, run_child

    key = (str(dataroot), version, scene, str(out), repeats)
    if key in _MEASURED:
        return _MEASURED[key]
    cmd = python_child(__file__, dataroot, version, "--scene", scene, "--check", out)
    runs = []
    for i in range(repeats):
        run = run_child(cmd)
        runs.append(run)
        log(f"  devkit reference [{i + 1}/{repeats}] {run.wall_s:.1f} s, {run.max_rss_mb:.0f} MiB "
            f"(construct {run.report['construct_s']:.1f} s, project {run.report['project_s'] * 1000:.0f} ms)")
    reports = [r.report for r in runs]
    result = {
        "command": " ".join(map(str, cmd)),
        "repeats": repeats,
        "process_wall_s": median(r.wall_s for r in runs),
        "load_wall_s": median(r.wall_s - r.report["tail_after_construct_s"] for r in runs),
        "count_wall_s": median(r.wall_s - r.report["tail_after_count_s"] for r in runs),
        "max_rss_mb": median(r.max_rss_mb for r in runs),
        "cpu_s": median(r.cpu_s for r in runs),
        **{k: median(rep[k] for rep in reports) for k in ("import_s", "construct_s", "count_s", "project_s")},
        "load_walls_s": [round(r.wall_s - r.report["tail_after_construct_s"], 3) for r in runs],
        "project_frames": reports[0]["project_frames"],
        "project_boxes": reports[0]["project_boxes"],
        "counts": reports[0]["counts"],
        "check": reports[0].get("check"),
    }
    _MEASURED[key] = result
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataroot")
    parser.add_argument("version")
    parser.add_argument("--scene", required=True, help="scene whose CAM_FRONT keyframes are projected")
    parser.add_argument("--check", metavar="OUT", help="compare the projection with nuparquet's from OUT")
    args = parser.parse_args()

    report: dict = {}
    start = time.perf_counter()
    from nuscenes.nuscenes import NuScenes

    report["import_s"] = time.perf_counter() - start

    start = time.perf_counter()
    nusc = NuScenes(version=args.version, dataroot=args.dataroot, verbose=False)
    construct_end = time.perf_counter()
    report["construct_s"] = construct_end - start

    start = time.perf_counter()
    counts = Counter(annotation["category_name"] for annotation in nusc.sample_annotation)
    count_end = time.perf_counter()
    report["count_s"] = count_end - start
    report["counts"] = dict(sorted(counts.items()))

    frame_tokens = scene_keyframe_tokens(nusc, args.scene)
    loops = []
    for _ in range(PROJECT_LOOPS):
        start = time.perf_counter()
        projected = devkit_project(nusc, frame_tokens)
        loops.append(time.perf_counter() - start)
    report["project_s"] = statistics.median(loops)
    report["project_loops_s"] = loops
    report["project_frames"] = len(frame_tokens)
    report["project_boxes"] = len(projected)

    if args.check:
        report["check"] = check_against_nuparquet(projected, args.check, args.scene)
    end = time.perf_counter()
    # What the process spent after construction and after the count: the parent subtracts these from the
    # process wall time to get the reference of row 1 (start-up + import + construction) and row 2 (+ count).
    report["tail_after_construct_s"] = end - construct_end
    report["tail_after_count_s"] = end - count_end
    print(json.dumps(report), flush=True)
    os._exit(0)  # skip freeing ~10 GB of dicts at exit: the devkit reference is not charged for its teardown


if __name__ == "__main__":
    main()
