"""Row 5: render one scene's CAM_FRONT at 1600x900 (keyframes, and --all-frames) vs a bare decode+encode loop;
and its six-camera mosaic (`--channel all`, keyframes) vs the bare loop over the same six streams.

    .venv/bin/python benchmarks/bench_render.py [--repeats 3]

Data: `.bench-cache/render` (2 scenes x 40 samples with synthetic 1600x900 JPEGs, sweeps included), converted;
its first scene, keyframes (5a) and all frames (5b). When ../shared/data/nuscenes-extract is present, also the
real nuScenes photos of its scene-0523 keyframes (5c): synthetic images (flat colours) decode and encode much
faster than photos, which makes the fixed costs of a render weigh more. For each case, a fresh process per
repeat:
- nuparquet: `nuparquet render OUT --scene S --channel CAM_FRONT --out X.mp4 --quiet [--all-frames]` (the
  defaults: output at scale 0.5 = 800x450, libx264 veryfast crf 23), whole-process wall time;
- reference: `bench_render.py --bare-child` running `render_reference.bare_decode_encode` (written by the
  rendering engineer) over the same JPEGs in the same order with the same size, fps and encoder settings:
  decode (the same reduced-size JPEG decode), resize, encode; nothing drawn, no query, one thread.
frames/s = frames / whole-process wall time for both; the in-process figures (the render library call, timed
around `render()`, vs the loop alone) are reported alongside. Target: ≥ 0.9× the reference's frames/s.

5d, the mosaic: `nuparquet render OUT --scene S --channel all --out X.mp4` (six 800x450 tiles in two rows:
2400x900) vs `render_reference.bare_mosaic_decode_encode` decoding the same six JPEGs per output at the tile
size, placing them in the same layout and encoding with the same settings.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

CHANNEL = "CAM_FRONT"
TARGET_RATIO = 0.9
MOSAIC = "all"
SCALE = 0.5
EXTRACT_SCENE = "scene-0523"  # real extract: 40 keyframes, Boston


def bare_child(paths_json: str, video: str, fps: float) -> None:
    from render_reference import bare_decode_encode

    paths = json.loads(Path(paths_json).read_text())
    size = (round(1600 * SCALE), round(900 * SCALE))
    result = bare_decode_encode(paths, video, size=size, fps=fps)
    print(json.dumps(result))


def bare_mosaic_child(paths_json: str, video: str, fps: float) -> None:
    from render_reference import bare_mosaic_decode_encode

    rows_of_paths = json.loads(Path(paths_json).read_text())
    tile = (round(1600 * SCALE), round(900 * SCALE))
    print(json.dumps(bare_mosaic_decode_encode(rows_of_paths, video, tile_size=tile, fps=fps)))


def render_child(out: str, scene: str, video: str, all_frames: bool, channel: str = CHANNEL) -> None:
    from nuparquet.rendering.video.pipeline import RenderOptions, render

    start = time.perf_counter()
    result = render(out, scene, video, RenderOptions(channel=channel, all_frames=all_frames, scale=SCALE))
    seconds = time.perf_counter() - start
    print(json.dumps({"frames": result.frames_written, "seconds": seconds, "fps": result.frames_written / seconds}))


def frame_paths(out: Path, scene: str, all_frames: bool) -> list[str]:
    import polars as pl

    import nuparquet

    ds = nuparquet.open(out)
    frames = ds.scan("frames").filter(pl.col("scene_name") == scene, pl.col("channel").cast(pl.String) == CHANNEL)
    if not all_frames:
        frames = frames.filter(pl.col("is_key_frame"))
    names = frames.sort("timestamp").select("filename").collect()["filename"].to_list()
    return [str(Path(ds.dataroot) / name) for name in names]


def mosaic_paths(out: Path, scene: str) -> list[list[list[str]]]:
    """Per keyframe output (samples in time order), the six cameras' images in the mosaic's rows."""
    import polars as pl

    import nuparquet

    ds = nuparquet.open(out)
    layout = [row for row in ds.channels["camera_layout"] if row]
    frames = (ds.scan("frames").filter(pl.col("scene_name") == scene, pl.col("is_key_frame"),
                                       pl.col("modality").cast(pl.String) == "camera")
              .select("sample_token", "timestamp", pl.col("channel").cast(pl.String), "filename").collect())
    by_sample = {}
    for sample, channel, name in frames.select("sample_token", "channel", "filename").iter_rows():
        by_sample.setdefault(sample, {})[channel] = str(Path(ds.dataroot) / name)
    order = frames.group_by("sample_token").agg(pl.col("timestamp").min()).sort("timestamp")["sample_token"]
    return [[[by_sample[sample][channel] for channel in row] for row in layout] for sample in order]


def mosaic_case(out: Path, scene: str, tmp: Path, repeats: int) -> tuple[dict, object]:
    """Row 5d: the six-camera keyframe mosaic vs the bare loop over the same six streams."""
    import bench_data as datasets
    from harness import Row, log, python_child, repeat, summarize, times

    log(f"row 5d: render {scene} --channel all (keyframes) vs the bare six-stream loop")
    paths = mosaic_paths(out, scene)
    paths_json = tmp / "paths-5d.json"
    paths_json.write_text(json.dumps(paths))
    cli = [*datasets.NUPARQUET, "render", str(out), "--scene", scene, "--channel", MOSAIC, "--out",
           str(tmp / "mosaic.mp4"), "--quiet"]
    library = python_child(__file__, "--render-child", out, scene, tmp / "mosaic-library.mp4", "--channel", MOSAIC)
    bare = python_child(__file__, "--bare-mosaic-child", paths_json, tmp / "bare-mosaic.mp4", "--fps", 2.0)
    ours = summarize(repeat(cli, repeats, label="nuparquet render --channel all"))
    ours_library = summarize(repeat(library, repeats, label="render() in-process, mosaic"), fps="fps",
                             frames="frames")
    reference = summarize(repeat(bare, repeats, label="bare six-stream decode+encode"), fps="fps")
    frames = len(paths)
    if ours_library["frames"] != frames:
        raise RuntimeError(f"render wrote {ours_library['frames']} mosaic frames, expected {frames}")
    ours_fps, bare_fps = frames / ours["wall_s"], frames / reference["wall_s"]
    speed, in_process = ours_fps / bare_fps, ours_library["fps"] / reference["fps"]
    figures = {"row": "5d", "scene": scene, "frames": frames, "cli": ours, "library": ours_library,
               "bare": reference, "ratio": speed, "in_process_ratio": in_process,
               "commands": {"cli": " ".join(map(str, cli)), "library": " ".join(map(str, library)),
                            "bare": " ".join(map(str, bare))}}
    row = Row(
        id="5d",
        benchmark=f"render {scene} six-camera mosaic (--channel all), six 1600x900 -> 800x450 tiles, 2400x900 "
        f"H.264, synthetic keyframes ({frames} frames, {6 * frames} images)",
        ours=f"{ours_fps:.1f} frames/s (process {ours['wall_s']:.2f} s, {ours['max_rss_mb']:.0f} MB); "
        f"in-process {ours_library['fps']:.1f} frames/s",
        reference=f"bare six-stream decode+encode {bare_fps:.1f} frames/s (process {reference['wall_s']:.2f} s); "
        f"in-process {reference['fps']:.1f} frames/s",
        ratio=f"{times(speed)} (in-process {times(in_process)})",
        target="report (its own row)",
        met=None,
    )
    return figures, row


def cases() -> list[tuple[str, str, Path, str, bool, float]]:
    """(row id, label, OUT, scene, all_frames, fps) of every render measured."""
    import bench_data as datasets
    from bench_project_scene import first_scene

    out = datasets.render_out()
    scene = first_scene(out)
    found = [("5a", "synthetic, keyframes", out, scene, False, 2.0),
             ("5b", "synthetic, all frames", out, scene, True, 12.0)]
    extract = datasets.extract_out()
    if extract is not None:  # real photos, keyframes only (the extract has no sweeps)
        found.append(("5c", "real nuScenes photos, keyframes", extract, EXTRACT_SCENE, False, 2.0))
    return found


def run(repeats: int = 3, only_mosaic: bool = False) -> dict:
    import bench_data as datasets
    from harness import Row, log, python_child, repeat, summarize, times

    rows, figures = [], {}
    tmp = datasets.CACHE / "render-run"  # videos and path lists; a fixed place keeps the commands readable
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        for row_id, label, out, scene, all_frames, fps in ([] if only_mosaic else cases()):
            log(f"row {row_id}: render {scene} {CHANNEL} ({label})")
            paths = frame_paths(out, scene, all_frames)
            paths_json = Path(tmp) / f"paths-{row_id}.json"
            paths_json.write_text(json.dumps(paths))
            flag = ["--all-frames"] if all_frames else []
            cli = [*datasets.NUPARQUET, "render", str(out), "--scene", scene, "--channel", CHANNEL, "--out",
                   str(Path(tmp) / "render.mp4"), "--quiet", *flag]
            library = python_child(__file__, "--render-child", out, scene, Path(tmp) / "library.mp4", *flag)
            bare = python_child(__file__, "--bare-child", paths_json, Path(tmp) / "bare.mp4", "--fps", fps)
            ours = summarize(repeat(cli, repeats, label=f"nuparquet render {label}"))
            ours_library = summarize(repeat(library, repeats, label=f"render() in-process {label}"),
                                     fps="fps", frames="frames")
            reference = summarize(repeat(bare, repeats, label=f"bare decode+encode {label}"), fps="fps")
            frames = len(paths)
            if ours_library["frames"] != frames:
                raise RuntimeError(f"render wrote {ours_library['frames']} frames, expected {frames}")
            ours_fps, bare_fps = frames / ours["wall_s"], frames / reference["wall_s"]
            speed = ours_fps / bare_fps
            in_process = ours_library["fps"] / reference["fps"]
            figures[label] = {"row": row_id, "scene": scene, "frames": frames, "cli": ours, "library": ours_library,
                              "bare": reference, "ratio": speed, "in_process_ratio": in_process,
                              "commands": {"cli": " ".join(map(str, cli)), "library": " ".join(map(str, library)),
                                           "bare": " ".join(map(str, bare))}}
            rows.append(Row(
                id=row_id,
                benchmark=f"render {scene} {CHANNEL} 1600x900 -> 800x450 H.264, {label} ({frames} frames)",
                ours=f"{ours_fps:.1f} frames/s (process {ours['wall_s']:.2f} s, {ours['max_rss_mb']:.0f} MB); "
                f"in-process {ours_library['fps']:.1f} frames/s",
                reference=f"bare decode+encode {bare_fps:.1f} frames/s (process {reference['wall_s']:.2f} s); "
                f"in-process {reference['fps']:.1f} frames/s",
                ratio=f"{times(speed)} (in-process {times(in_process)})",
                target=f"≥ {TARGET_RATIO}× its frames/s",
                met=speed >= TARGET_RATIO,
            ))
        out = datasets.render_out()
        from bench_project_scene import first_scene

        figures["mosaic, keyframes"], row = mosaic_case(out, first_scene(out), tmp, repeats)
        rows.append(row)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {"name": "render", "modes": figures, "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--bare-child", nargs=2, metavar=("PATHS_JSON", "VIDEO"), help=argparse.SUPPRESS)
    parser.add_argument("--fps", type=float, default=2.0, help=argparse.SUPPRESS)
    parser.add_argument("--render-child", nargs=3, metavar=("OUT", "SCENE", "VIDEO"), help=argparse.SUPPRESS)
    parser.add_argument("--all-frames", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--channel", default=CHANNEL, help=argparse.SUPPRESS)
    parser.add_argument("--bare-mosaic-child", nargs=2, metavar=("PATHS_JSON", "VIDEO"), help=argparse.SUPPRESS)
    parser.add_argument("--only-mosaic", action="store_true", help="run row 5d only")
    args = parser.parse_args()
    if args.bare_child:
        bare_child(*args.bare_child, args.fps)
        return
    if args.bare_mosaic_child:
        bare_mosaic_child(*args.bare_mosaic_child, args.fps)
        return
    if args.render_child:
        render_child(*args.render_child, args.all_frames, args.channel)
        return
    from harness import report_alone

    report_alone(run(args.repeats, args.only_mosaic))


if __name__ == "__main__":
    main()
