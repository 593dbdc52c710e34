"""Every sensor of a sample in one picture, as devkit `render_sample` gathers them: each lidar seen from above, the
radars fused into one view from above (boxes drawn once), and every camera with its boxes, or with the lidar's
lidarseg / panoptic points instead when labels are asked for. Tiles of one size: the cameras in the dataset's
camera layout (front row over back row, `Dataset.channels`), the views from above in a row of their own before
them, square and centred in their tile. Returns (H, W, 3) uint8 RGB.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl

from nuparquet.dataset import as_dataset
from nuparquet.errors import InputError, UsageError
from nuparquet.rendering import draw
from nuparquet.rendering import colorings
from nuparquet.rendering.colorings import PointColor
from nuparquet.rendering.pictures.clouds import frame_frame
from nuparquet.rendering.mosaic import compose
from nuparquet.rendering.pictures.pointcloud_image import points_on_image
from nuparquet.rendering.pictures.sample_data import camera_image, top_view, visibility_name


def _square_in_tile(square: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    width, height = size
    tile = np.zeros((height, width, 3), np.uint8)
    side = min(square.shape[0], height, width)
    x0, y0 = (width - side) // 2, (height - side) // 2
    tile[y0:y0 + side, x0:x0 + side] = square[:side, :side]
    return tile


def render_sample(dataset_or_path, token: str, box_vis_level="any", nsweeps: int = 1, *,
                  point_color: PointColor = "depth", filter_lidarseg_labels: Sequence[int] | None = None,
                  lidarseg_preds_bin_path=None, scale: float = 0.35, axes_limit: float = 40,
                  underlay_map: bool = True, radar_filters: bool = True) -> np.ndarray:
    """Sample `token`'s keyframes of every sensor in one picture (the module docstring); `scale` sizes the camera
    tiles (the views from above are as high as they are); `point_color` "lidarseg" or "panoptic" colours the
    reference lidar's view and its points on every camera by their labels (the devkit's `show_lidarseg`,
    `show_panoptic`), "depth" (default) draws the cameras with their boxes."""
    dataset = as_dataset(dataset_or_path)
    visibility = visibility_name(box_vis_level)
    keyframes = (dataset.scan("frames").filter((pl.col("sample_token") == token) & pl.col("is_key_frame"))
                 .with_columns(pl.col("channel").cast(pl.String), pl.col("modality").cast(pl.String))
                 .sort("channel").collect())
    if keyframes.is_empty():
        raise UsageError(f"no sample {token!r} (or no keyframe of it) in {dataset.root}")
    by_channel = {row["channel"]: row for row in keyframes.iter_rows(named=True)}
    cameras = keyframes.filter(pl.col("modality") == "camera")
    size = (max(2, round(int(cameras["width"].max()) * scale)), max(2, round(int(cameras["height"].max()) * scale))) \
        if cameras.height else (round(900 * scale), round(900 * scale))
    label_mode = colorings.label_mode(point_color)
    if point_color not in ("depth", *colorings.LABEL_COLORS):
        raise UsageError(f"a sample's picture colours points by depth, lidarseg or panoptic, not {point_color}")
    reference = dataset.channels.get("reference_lidar")
    views = dict(with_anns=True, axes_limit=axes_limit, nsweeps=nsweeps, underlay_map=underlay_map, flat=True,
                 point_color="depth", legend_on=False, keep_classes=filter_lidarseg_labels,
                 radar_filters=radar_filters, size_px=size[1])
    top_tiles = []
    for modality in ("lidar", "radar"):
        rows = [r for r in keyframes.filter(pl.col("modality") == modality).iter_rows(named=True)]
        if modality == "lidar":
            for row in rows:
                labelled = label_mode is not None and row["channel"] == reference
                top_tiles.append(top_view(dataset, [row],
                                          preds_path=lidarseg_preds_bin_path if labelled else None,
                                          **(views | {"point_color": point_color if labelled else "depth",
                                                      "nsweeps": 1 if labelled else nsweeps})))
        elif rows:
            top_tiles.append(top_view(dataset, rows, preds_path=None, **views))
    layout: list[list[np.ndarray]] = [[_square_in_tile(t, size) for t in top_tiles]] if top_tiles else []
    for channels in dataset.channels.get("camera_layout", []):
        row_tiles = []
        for channel in channels:
            if channel not in by_channel:
                row_tiles.append(draw.placeholder(*size, f"{channel}: no keyframe"))
                continue
            camera_rows = frame_frame(dataset, by_channel[channel]["token"])
            try:
                if label_mode and reference in by_channel:
                    tile = points_on_image(dataset, camera_rows, frame_frame(dataset, by_channel[reference]["token"]),
                                           scale=scale, point_color=point_color,
                                           keep_classes=filter_lidarseg_labels, preds_path=lidarseg_preds_bin_path)
                else:
                    tile = camera_image(dataset, camera_rows, visibility=visibility, scale=scale)
                    from nuparquet.rendering.legend import draw_caption

                    draw_caption(tile, channel)
            except InputError:
                tile = draw.placeholder(*size, f"{channel}: no image")
            if tile.shape[:2] != (size[1], size[0]):
                import cv2

                tile = cv2.resize(tile, size, interpolation=cv2.INTER_AREA)
            row_tiles.append(tile)
        if row_tiles:
            layout.append(row_tiles)
    tiles = [tile for row in layout for tile in row]
    picture = compose(tiles, [len(row) for row in layout], *size)
    return np.ascontiguousarray(picture[..., ::-1])
