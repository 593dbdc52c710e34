"""The render job: one scene, one camera (or all six tiled), boxes drawn on every output frame, into an H.264
MP4 and/or a folder of images.

```python
from nuparquet.render.pipeline import RenderOptions, render
result = render("OUT", RenderOptions(scene="scene-0061", channel="CAM_FRONT", out="scene-0061.mp4"))
```

How the work is laid out (STYLE.md: vectorise over the batch):

1. One polars query (three lazy scans collected together with `collect_all`): the scene's camera frames of
   the channel(s), its annotations and its samples (plus the LIDAR_TOP keyframes with `lidar=True`).
2. One `project_boxes` call for all frames, then every box's 2D segments, colour, label and drawing order
   at once as numpy arrays.
3. A loop over output frames only: a thread pool decodes JPEGs (and loads lidar points) a few frames
   ahead — OpenCV releases the GIL — while the main thread draws and hands frames to x264, which runs
   its own threads.
"""

from __future__ import annotations

import sys
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import polars as pl

from nuparquet.errors import InputError, UsageError
from nuparquet.render import draw
from nuparquet.render.mosaic import match_frames_by_time, mosaic_size, tile_cameras, time_steps_us
from nuparquet.render.project import ProjectedBoxes, project_boxes, project_lidar_to_image
from nuparquet.render.options import ALL_CHANNELS, CAMERA_CHANNELS, LIDAR_CHANNEL, RenderOptions
from nuparquet.render.video import VideoWriter, even_size

LIDAR_MAX_DEPTH_M = 60.0  # colour scale of projected lidar points


_DECODE_AHEAD = 6  # output frames decoded ahead of the one being drawn

_FRAME_COLUMNS = [
    "token", "sample_token", "scene_token", "channel", "timestamp", "is_key_frame", "filename", "width", "height",
    "ego_translation", "ego_rotation", "sensor_translation", "sensor_rotation", "camera_intrinsic",
]
_ANNOTATION_COLUMNS = ["token", "sample_token", "instance_token", "category_name", "translation", "size", "rotation"]


@dataclass
class RenderResult:
    """What a render wrote. `missing` lists the image files that were missing or unreadable (skipped)."""

    scene: str
    channel: str
    frames_written: int
    frames_skipped: int
    width: int
    height: int
    fps: float
    out: Path | None
    frames_dir: Path | None
    missing: list[str] = field(default_factory=list)


@dataclass
class _Scene:
    """The rows one render needs, collected by one query."""

    cameras: pl.DataFrame  # camera frames of the channel(s), sorted by channel, timestamp
    annotations: pl.DataFrame
    samples: pl.DataFrame
    lidar: pl.DataFrame  # LIDAR_TOP keyframes (empty unless asked for)


def _dataset(dataset_or_path):
    if hasattr(dataset_or_path, "scan"):
        return dataset_or_path
    import nuparquet

    return nuparquet.open(dataset_or_path)


def _channel_filter(options: RenderOptions) -> pl.Expr:
    channels = list(CAMERA_CHANNELS) if options.mosaic else [options.channel]
    return pl.col("channel").cast(pl.String).is_in(channels)


def load_scene(dataset, options: RenderOptions) -> _Scene:
    """Run the render's one query: camera frames, annotations and samples of the scene (lidar keyframes too)."""
    scene = pl.col("scene_name") == options.scene
    frames = dataset.scan("frames").filter(scene)
    wanted = _channel_filter(options)
    if not options.all_frames:
        wanted = wanted & pl.col("is_key_frame")
    if options.lidar:
        wanted = wanted | ((pl.col("channel").cast(pl.String) == LIDAR_CHANNEL) & pl.col("is_key_frame"))
    frames = frames.filter(wanted).select(_FRAME_COLUMNS).with_columns(pl.col("channel").cast(pl.String))
    annotations = dataset.scan("annotations").filter(scene).select(_ANNOTATION_COLUMNS)
    samples = (
        dataset.scan("tables/sample")
        .join(frames.select("scene_token").unique(), on="scene_token", how="semi")
        .select("token", "timestamp", "prev", "scene_token")
    )
    frames_df, annotations_df, samples_df = pl.collect_all([frames, annotations, samples])
    is_lidar = frames_df["channel"] == LIDAR_CHANNEL
    cameras = frames_df.filter(~is_lidar).sort("channel", "timestamp", maintain_order=True)
    if cameras.height == 0:
        _raise_unknown(dataset, options)
    return _Scene(cameras=cameras, annotations=annotations_df, samples=samples_df, lidar=frames_df.filter(is_lidar))


def _raise_unknown(dataset, options: RenderOptions) -> None:
    """The query found no camera frame: say whether the scene or the channel is unknown, listing valid names."""
    listing = (
        dataset.scan("frames")
        .filter(pl.col("modality").cast(pl.String) == "camera")
        .select("scene_name", pl.col("channel").cast(pl.String))
        .unique()
        .collect()
    )
    scenes = sorted(listing["scene_name"].unique().to_list())
    if options.scene not in scenes:
        raise UsageError(f"unknown scene {options.scene!r}; valid scenes: {', '.join(scenes) or '(none)'}")
    channels = sorted(listing.filter(pl.col("scene_name") == options.scene)["channel"].unique().to_list())
    raise UsageError(
        f"unknown channel {options.channel!r} for {options.scene}; valid channels: {', '.join(channels + [ALL_CHANNELS])}"
    )


def plan_outputs(
    cameras: pl.DataFrame, samples: pl.DataFrame, options: RenderOptions
) -> tuple[tuple[str, ...], np.ndarray]:
    """Which camera row goes into each tile of each output frame.

    One channel: every row, in time order. Mosaic of keyframes: one output per sample. Mosaic of all frames:
    devkit `render_scene`'s time steps between the first and last sample (see `mosaic`).

    Returns:
        channels: (C,) the tile channels (one, or the six of MOSAIC_LAYOUT).
        rows: (T, C) int64 rows of `cameras` (-1: that camera has no frame for this output).
    """
    if not options.mosaic:
        return (options.channel,), np.arange(cameras.height, dtype=np.int64)[:, None]
    channel_rows = {
        channel: np.flatnonzero((cameras["channel"] == channel).to_numpy()) for channel in CAMERA_CHANNELS
    }
    keyframes = cameras.with_row_index("row").filter(pl.col("is_key_frame"))
    if not options.all_frames:
        # Keyframes: one output per sample, each camera showing its keyframe of that sample.
        by_sample = (
            keyframes.group_by("sample_token")
            .agg(pl.col("timestamp").min().alias("t"), pl.col("channel"), pl.col("row"))
            .sort("t")
        )
        rows = np.full((by_sample.height, len(CAMERA_CHANNELS)), -1, dtype=np.int64)
        column_of = {channel: index for index, channel in enumerate(CAMERA_CHANNELS)}
        exploded = by_sample.with_row_index("output").explode("channel", "row")
        outputs = exploded["output"].to_numpy()
        columns = np.array([column_of[c] for c in exploded["channel"].to_list()], dtype=np.int64)
        rows[outputs, columns] = exploded["row"].to_numpy()
        return CAMERA_CHANNELS, rows
    # Every frame: devkit render_scene, time steps of 1 / fps from the scene's first to its last sample.
    samples = samples.sort("timestamp")
    first_sample_token = samples["token"][0]
    times_us = time_steps_us(int(samples["timestamp"][0]), int(samples["timestamp"][-1]), options.frame_rate)
    timestamps = cameras["timestamp"].to_numpy()
    starts = (cameras["sample_token"] == first_sample_token).to_numpy() & cameras["is_key_frame"].to_numpy()
    rows = np.full((len(times_us), len(CAMERA_CHANNELS)), -1, dtype=np.int64)
    for column, channel in enumerate(CAMERA_CHANNELS):  # six channels
        channel_index = channel_rows[channel]
        if len(channel_index) == 0:
            continue
        # The devkit starts each camera at its keyframe of the first sample.
        start = int(np.argmax(starts[channel_index])) if starts[channel_index].any() else 0
        rows[:, column] = channel_index[match_frames_by_time(timestamps[channel_index], start, times_us)]
    return CAMERA_CHANNELS, rows


@dataclass
class _Overlay:
    """Every box of the render, ready to draw: sorted by camera row, far to near within a row."""

    segments_px: np.ndarray  # (M, 14, 2, 2) in output-tile pixels
    keep: np.ndarray  # (M, 14)
    colors_rgb: np.ndarray  # (M, 3)
    labels: list[str] | None
    row_start: np.ndarray  # (F + 1,) boxes of camera row f are [row_start[f], row_start[f + 1])


def _category_colors(category_names: np.ndarray) -> np.ndarray:
    from nuparquet.palette import category_rgb

    names, inverse = np.unique(category_names.astype(str), return_inverse=True)
    palette = np.array([category_rgb(name) for name in names], dtype=np.uint8).reshape(-1, 3)
    return palette[inverse.reshape(-1)] if len(names) else np.zeros((0, 3), dtype=np.uint8)


def build_overlay(
    cameras: pl.DataFrame,
    annotations: pl.DataFrame,
    samples: pl.DataFrame,
    tile_size: tuple[int, int],
    options: RenderOptions,
) -> _Overlay:
    """Project every box of every camera row at once and turn them into drawable segments in tile pixels."""
    projected: ProjectedBoxes = project_boxes(cameras, annotations, samples, visibility="none" if options.clip else "any")
    widths = cameras["width"].to_numpy().astype(np.float64)
    heights = cameras["height"].to_numpy().astype(np.float64)
    scale_xy = np.stack([tile_size[0] / widths, tile_size[1] / heights], axis=1)  # (F, 2)
    frame = projected.frame_index.astype(np.int64)
    box_scale = scale_xy[frame]  # (M, 2)
    if options.clip:
        intrinsic = np.asarray(cameras["camera_intrinsic"].to_numpy(), dtype=np.float64).reshape(-1, 3, 3)
        sx, sy = box_scale[:, 0], box_scale[:, 1]
        image_from_full = np.zeros((len(frame), 3, 3))
        image_from_full[:, 0, 0], image_from_full[:, 0, 2] = sx, (sx - 1.0) / 2.0
        image_from_full[:, 1, 1], image_from_full[:, 1, 2] = sy, (sy - 1.0) / 2.0
        image_from_full[:, 2, 2] = 1.0
        segments_px, keep = draw.clip_box_segments(projected.corners_camera_m, image_from_full @ intrinsic[frame])
        shown = draw.segments_touch_image(segments_px, keep, tile_size[0], tile_size[1])
    else:
        corners_px = projected.corners_px * box_scale[:, None, :] + (box_scale[:, None, :] - 1.0) / 2.0
        segments_px = draw.box_segments_px(corners_px)
        keep = np.ones(segments_px.shape[:2], dtype=bool)
        shown = np.ones(len(frame), dtype=bool)
    order = np.lexsort((-projected.distance_m, frame))  # by camera row, then far to near
    order = order[shown[order]]
    frame = frame[order]
    if options.labels == "category":
        labels = [draw.short_category(name) for name in projected.category_name[order].tolist()]
    elif options.labels == "track":
        labels = [draw.short_track(token) for token in projected.instance_token[order].tolist()]
    else:
        labels = None
    return _Overlay(
        segments_px=segments_px[order],
        keep=keep[order],
        colors_rgb=_category_colors(projected.category_name[order]),
        labels=labels,
        row_start=np.searchsorted(frame, np.arange(cameras.height + 1), side="left"),
    )


def _reduced_decode_flag(scale: float) -> tuple[int, int]:
    """The cheapest OpenCV decode mode that still gives at least `scale` of the full size (JPEG DCT scaling)."""
    for factor, flag in ((8, cv2.IMREAD_REDUCED_COLOR_8), (4, cv2.IMREAD_REDUCED_COLOR_4), (2, cv2.IMREAD_REDUCED_COLOR_2)):
        if scale <= 1.0 / factor:
            return flag, factor
    return cv2.IMREAD_COLOR, 1


def decode_image(path: str, size: tuple[int, int], scale: float) -> np.ndarray | None:
    """Read an image file resized to `size` (width, height), or None if it is missing or not decodable.

    JPEGs are decoded directly at 1/2, 1/4 or 1/8 size when `scale` allows (libjpeg's DCT scaling: several
    times cheaper than a full decode), then resized with area averaging.
    """
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError:
        return None
    if data.size == 0:
        return None
    flag, _ = _reduced_decode_flag(scale)
    image = cv2.imdecode(data, flag)
    if image is None:
        return None
    if image.shape[1] != size[0] or image.shape[0] != size[1]:
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return image


def _load_lidar(lidar_row: dict | None, camera_row: dict, dataroot: Path, tile_size):
    """Projected lidar points for one keyframe camera row: (uv_tile (K, 2), depth (K,)), or (None, path) if the
    point cloud is missing or unreadable."""
    from nuparquet.pointcloud import load_lidar_bin

    if lidar_row is None:
        return None, None
    path = str(dataroot / lidar_row["filename"])
    try:
        points = load_lidar_bin(path)
    except (OSError, ValueError):
        return None, path
    uv, depth, _ = project_lidar_to_image(points, lidar_row, camera_row)
    scale = (tile_size[0] / camera_row["width"], tile_size[1] / camera_row["height"])
    return (draw.scale_pixels(uv, scale), depth), None


def render(dataset_or_path, options: RenderOptions) -> RenderResult:
    """Render one scene as described by `options`; see the module docstring.

    Raises:
        UsageError: bad options, unknown scene or channel, a dataroot that does not exist.
        InputError: with on_missing="error", the first missing or unreadable image (named by path); with
            "skip", when no frame at all could be rendered.
    """
    options.check()
    dataset = _dataset(dataset_or_path)
    dataroot = Path(options.dataroot) if options.dataroot is not None else (
        Path(dataset.dataroot) if dataset.dataroot else None
    )
    if dataroot is None or not dataroot.is_dir():
        raise UsageError(
            f"image folder (dataroot) {dataroot} does not exist; pass --dataroot PATH (the folder holding samples/)"
        )

    scene = load_scene(dataset, options)
    cameras = scene.cameras
    full_width, full_height = int(cameras["width"].max()), int(cameras["height"].max())
    tile_size = (max(2, round(full_width * options.scale)), max(2, round(full_height * options.scale)))
    channels, plan = plan_outputs(cameras, scene.samples, options)
    overlay = build_overlay(cameras, scene.annotations, scene.samples, tile_size, options)
    out_size = mosaic_size(*tile_size) if options.mosaic else tile_size

    lidar_of_row: dict[int, dict] = {}
    if options.lidar and scene.lidar.height:
        lidar_rows = {row["sample_token"]: row for row in scene.lidar.iter_rows(named=True)}
        for index, (sample_token, is_key) in enumerate(zip(cameras["sample_token"], cameras["is_key_frame"])):
            if is_key and sample_token in lidar_rows:
                lidar_of_row[index] = lidar_rows[sample_token]
    camera_rows = cameras.select(
        "filename", "width", "height", "ego_translation", "ego_rotation", "sensor_translation", "sensor_rotation",
        "camera_intrinsic",
    )
    filenames = [str(dataroot / name) for name in camera_rows["filename"].to_list()]

    widths = draw.line_widths(options.scale)
    font_scale = max(0.3, 0.8 * options.scale)
    point_size = max(1, round(3 * options.scale))

    def decode_output(t: int):
        """Decode the tiles of output t (thread pool): per tile (image | None, lidar | None, missing paths)."""
        tiles = []
        for row in plan[t].tolist():
            if row < 0:
                tiles.append((None, None, []))
                continue
            image = decode_image(filenames[row], tile_size, options.scale)
            missing = [] if image is not None else [filenames[row]]
            points = None
            if image is not None and row in lidar_of_row:
                points, lidar_missing = _load_lidar(
                    lidar_of_row[row], camera_rows.row(row, named=True), dataroot, tile_size
                )
                if lidar_missing:
                    missing.append(lidar_missing)
            tiles.append((image, points, missing))
        return tiles

    def annotate(row: int, image: np.ndarray, points) -> np.ndarray:
        if points is not None:
            draw.draw_points(image, points[0], points[1], max_depth_m=LIDAR_MAX_DEPTH_M, size_px=point_size)
        start, stop = overlay.row_start[row], overlay.row_start[row + 1]
        draw.draw_boxes(
            image,
            overlay.segments_px[start:stop],
            overlay.colors_rgb[start:stop],
            keep=overlay.keep[start:stop],
            labels=None if overlay.labels is None else overlay.labels[start:stop],
            widths=widths,
            font_scale=font_scale,
        )
        return image

    frames_dir = Path(options.frames_dir) if options.frames_dir is not None else None
    if frames_dir is not None:
        frames_dir.mkdir(parents=True, exist_ok=True)
    out_path = Path(options.out) if options.out is not None else None
    writer: VideoWriter | None = None
    missing: list[str] = []
    seen_missing: set[str] = set()
    written = skipped = 0
    last_tile: dict[int, tuple[int, np.ndarray]] = {}  # mosaic column -> (camera row, drawn tile): reuse repeats
    progress = _progress(len(plan), f"{options.scene} {options.channel}", options.progress)

    pool = ThreadPoolExecutor(max_workers=max(1, options.threads), thread_name_prefix="nuparquet-decode")
    pending: deque[Future] = deque()
    image_writes: list[Future] = []
    next_to_submit = 0
    try:
        for t in range(len(plan)):
            while next_to_submit < len(plan) and len(pending) < _DECODE_AHEAD:
                pending.append(pool.submit(decode_output, next_to_submit))
                next_to_submit += 1
            tiles = pending.popleft().result()

            for _, _, paths in tiles:
                for path in paths:
                    if options.on_missing == "error":
                        raise InputError(
                            f"missing or unreadable file: {path} (--on-missing skip renders without it; "
                            "--dataroot says where the images are)"
                        )
                    if path not in seen_missing:
                        seen_missing.add(path)
                        missing.append(path)

            if not options.mosaic:
                image, points, _ = tiles[0]
                if image is None:
                    skipped += 1
                    progress.update(1)
                    continue
                picture = annotate(int(plan[t, 0]), image, points)
            else:
                if all(image is None for image, _, _ in tiles):
                    skipped += 1
                    progress.update(1)
                    continue
                drawn = {}
                for column, (channel, (image, points, _)) in enumerate(zip(channels, tiles)):
                    row = int(plan[t, column])
                    if image is None:
                        drawn[channel] = draw.placeholder(*tile_size, f"{channel}: no image")
                    elif column in last_tile and last_tile[column][0] == row:
                        drawn[channel] = last_tile[column][1]
                    else:
                        drawn[channel] = annotate(row, image, points)
                        last_tile[column] = (row, drawn[channel])
                picture = tile_cameras(drawn, *tile_size)

            if out_path is not None:
                if writer is None:
                    writer = VideoWriter(
                        out_path, width=out_size[0], height=out_size[1], fps=options.frame_rate, crf=options.crf,
                        preset=options.preset,
                    )
                writer.write(picture)
            if frames_dir is not None:
                target = frames_dir / f"{written:05d}.{options.frame_format}"
                image_writes.append(pool.submit(_write_image, target, picture))  # never modified after this
            written += 1
            progress.update(1)

        for future in image_writes:
            future.result()
        if written == 0:
            raise InputError(
                f"no frame of {options.scene} {options.channel} could be rendered: all {len(missing)} image "
                f"file(s) are missing or unreadable, e.g. {missing[0] if missing else '?'} (is --dataroot right?)"
            )
        if writer is not None:
            writer.close()
            writer = None
    finally:
        progress.close()
        for future in pending:
            future.cancel()
        pool.shutdown(wait=True, cancel_futures=True)
        if writer is not None:  # an error stopped the render: do not leave a truncated MP4 behind
            writer.abort()

    video_size = even_size(*out_size)
    return RenderResult(
        scene=options.scene,
        channel=options.channel,
        frames_written=written,
        frames_skipped=skipped,
        width=video_size[0] if out_path is not None else out_size[0],
        height=video_size[1] if out_path is not None else out_size[1],
        fps=options.frame_rate,
        out=out_path,
        frames_dir=frames_dir,
        missing=missing,
    )


def _write_image(path: Path, image_bgr: np.ndarray) -> None:
    if not cv2.imwrite(str(path), image_bgr):
        raise OSError(f"could not write {path}")


class _NoProgress:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def _progress(total: int, description: str, enabled: bool):
    if not enabled:
        return _NoProgress()
    from tqdm import tqdm

    return tqdm(total=total, desc=description, unit="frame", file=sys.stderr, dynamic_ncols=True)
