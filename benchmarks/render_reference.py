"""Rendering speed against its floor: `nuparquet render` vs a bare loop that decodes the same JPEGs and encodes
them with the same encoder settings, drawing nothing.

    .venv/bin/python benchmarks/render_reference.py [--scenes 1] [--samples 40] [--scale 0.5] [--workdir DIR]

Synthesises a dataset with 1600x900 camera images (sweeps included), converts it, then times for one scene's
CAM_FRONT: keyframes (2 fps) and --all-frames (12 fps). `bare_decode_encode` is the reference loop, importable
by other benchmarks (`from render_reference import bare_decode_encode`).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import polars as pl

from nuparquet.rendering.decode import decode_image
from nuparquet.rendering.video.video import DEFAULT_CRF, DEFAULT_PRESET, VideoWriter


def bare_decode_encode(
    paths: list[str],
    out: str | Path,
    *,
    size: tuple[int, int] = (800, 450),
    fps: float = 2.0,
    crf: int = DEFAULT_CRF,
    preset: str = DEFAULT_PRESET,
    reduced_decode: bool = True,
) -> dict:
    """Decode each JPEG, resize it to `size` and encode it to H.264 (libx264, yuv420p) — one thread, nothing drawn.

    Args:
        paths: image files, in output order.
        out: the MP4 to write.
        size: (width, height) of the video.
        reduced_decode: decode at 1/2, 1/4 or 1/8 size where the scale allows, as `nuparquet render` does; False
            decodes every image at full size and resizes.

    Returns:
        {"frames": n, "seconds": wall time, "fps": n / seconds}.
    """
    start = time.perf_counter()
    scale = size[0] / 1600
    with VideoWriter(out, width=size[0], height=size[1], fps=fps, crf=crf, preset=preset) as video:
        for path in paths:
            if reduced_decode:
                image = decode_image(path, size, scale)
            else:
                image = cv2.imdecode(np.fromfile(path, dtype=np.uint8), cv2.IMREAD_COLOR)
                image = cv2.resize(image, size, interpolation=cv2.INTER_AREA) if image.shape[1::-1] != size else image
            video.write(image)
    seconds = time.perf_counter() - start
    return {"frames": len(paths), "seconds": seconds, "fps": len(paths) / seconds}


def bare_mosaic_decode_encode(
    rows_of_paths: list[list[list[str]]],
    out: str | Path,
    *,
    tile_size: tuple[int, int] = (800, 450),
    fps: float = 2.0,
    crf: int = DEFAULT_CRF,
    preset: str = DEFAULT_PRESET,
) -> dict:
    """The six-camera floor: for each output, decode every camera's JPEG at the tile size (the same reduced
    decode), place the tiles in their rows, encode the picture — one thread, nothing drawn, no query.

    Args:
        rows_of_paths: per output, rows of image files (front row first, each left to right).
        tile_size: (width, height) of one tile; the video is (columns * width, rows * height).
    """
    start = time.perf_counter()
    scale = tile_size[0] / 1600
    columns, rows = len(rows_of_paths[0][0]), len(rows_of_paths[0])
    size = (columns * tile_size[0], rows * tile_size[1])
    with VideoWriter(out, width=size[0], height=size[1], fps=fps, crf=crf, preset=preset) as video:
        for layout in rows_of_paths:
            picture = np.concatenate([np.concatenate([decode_image(path, tile_size, scale) for path in row], axis=1)
                                      for row in layout], axis=0)
            video.write(picture)
    seconds = time.perf_counter() - start
    return {"frames": len(rows_of_paths), "seconds": seconds, "fps": len(rows_of_paths) / seconds}


def _time_render(out_dir: Path, scene: str, all_frames: bool, scale: float, video: Path) -> dict:
    from nuparquet.rendering.video.pipeline import RenderOptions, render

    start = time.perf_counter()
    result = render(out_dir, scene, video, RenderOptions(channel="CAM_FRONT", all_frames=all_frames, scale=scale))
    seconds = time.perf_counter() - start
    return {"frames": result.frames_written, "seconds": seconds, "fps": result.frames_written / seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=1)
    parser.add_argument("--samples", type=int, default=40, help="samples (keyframes) per scene")
    parser.add_argument("--scale", type=float, default=0.5)
    parser.add_argument("--repeat", type=int, default=3, help="best of N runs")
    parser.add_argument("--workdir", type=Path, help="keep the synthetic data here (default: a temporary folder)")
    args = parser.parse_args()

    import nuparquet
    from nuparquet.conversion import convert
    from nuparquet.synth import synthesize

    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        root, out = work / "synth", work / "out"
        if not (out / "manifest.json").exists():
            synthesize(root, scenes=args.scenes, samples_per_scene=args.samples, with_images=True, with_lidar=True, seed=0)
            convert(root, "v1.0-synth", out, overwrite=True)
        ds = nuparquet.open(out)
        scene = ds.scan("scenes").select("name").collect()["name"].sort()[0]
        frames = ds.scan("frames").filter(
            pl.col("scene_name") == scene, pl.col("channel").cast(pl.String) == "CAM_FRONT"
        ).sort("timestamp").collect()
        size = (round(1600 * args.scale), round(900 * args.scale))
        print(f"scene {scene}, CAM_FRONT, {size[0]}x{size[1]}, libx264 {DEFAULT_PRESET} crf {DEFAULT_CRF}; best of {args.repeat}")
        print(f"{'mode':<12} {'frames':>6} {'render fps':>11} {'bare fps':>9} {'bare full-decode fps':>21}")
        for mode, all_frames, fps in (("keyframes", False, 2.0), ("all-frames", True, 12.0)):
            selected = frames if all_frames else frames.filter(pl.col("is_key_frame"))
            paths = [str(Path(ds.dataroot) / name) for name in selected["filename"].to_list()]
            rendered = max((_time_render(out, scene, all_frames, args.scale, work / "r.mp4") for _ in range(args.repeat)),
                           key=lambda r: r["fps"])
            bare = max((bare_decode_encode(paths, work / "b.mp4", size=size, fps=fps) for _ in range(args.repeat)),
                       key=lambda r: r["fps"])
            full = max((bare_decode_encode(paths, work / "f.mp4", size=size, fps=fps, reduced_decode=False)
                        for _ in range(args.repeat)), key=lambda r: r["fps"])
            print(f"{mode:<12} {rendered['frames']:>6} {rendered['fps']:>11.1f} {bare['fps']:>9.1f} {full['fps']:>21.1f}")


if __name__ == "__main__":
    main()
