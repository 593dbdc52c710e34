"""One nuImages image with its annotations, as `NuImages.render_image` draws it (OpenCV and numpy, headless).

The devkit pastes each mask onto the image through Pillow's `ImageDraw.bitmap` with the mask at 128 (every
channel becomes `(pixel * 127 + colour * 128) / 255`, Pillow's rounding), surfaces first, then the objects in
object_ann.json's order, each object's box drawn over its mask as `ImageDraw.rectangle(bbox, width=w)` (w pixels
inward from the inclusive corners) and, with `with_category`, its name at the box's top-left corner. Masks and
boxes here are those pixels exactly; the label is OpenCV's font, not Pillow's. As in the devkit, an object without
a mask is not drawn at all (neither mask nor box). The devkit then shows the RGBA picture in matplotlib (the
masks' alpha, 191, over a white figure); this returns the RGB channels, opaque, at `render_scale` of the image.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
import polars as pl

from nuparquet.dataset import as_dataset
from nuparquet.errors import InputError, UsageError
from nuparquet.nuimages.masks import decode_rows, image_annotations
from nuparquet.rendering.palette import category_rgb

ANNOTATION_TYPES = ("all", "surfaces", "objects", "none")
MASK_VALUE = 128  # the devkit's `Image.fromarray(mask * 128)`


def paste(image_rgb: np.ndarray, mask: np.ndarray, color_rgb) -> None:
    """Pillow's paste of a solid colour through a mask of value 128 (its `BLEND` with `DIV255` rounding), in place."""
    inside = mask.astype(bool)
    pixels = image_rgb[inside].astype(np.int32)
    blended = pixels * (255 - MASK_VALUE) + np.asarray(color_rgb, np.int32) * MASK_VALUE + 128
    image_rgb[inside] = (((blended >> 8) + blended) >> 8).astype(np.uint8)


def rectangle(image_rgb: np.ndarray, bbox: Sequence[int], color_rgb, width: int) -> None:
    """Pillow's `rectangle(bbox, outline=colour, width=width)`: bands `width` pixels wide inside the inclusive
    corners (x0, y0) and (x1, y1), clipped to the image, in place."""
    x0, y0, x1, y1 = (int(v) for v in bbox)
    height, w_px = image_rgb.shape[:2]
    if width <= 0 or x1 < x0 or y1 < y0:
        return
    color = np.asarray(color_rgb, np.uint8)

    def band(ya, yb, xa, xb):
        ya, yb, xa, xb = max(ya, 0), min(yb, height - 1), max(xa, 0), min(xb, w_px - 1)
        if ya <= yb and xa <= xb:
            image_rgb[ya:yb + 1, xa:xb + 1] = color

    band(y0, min(y0 + width - 1, y1), x0, x1)
    band(max(y1 - width + 1, y0), y1, x0, x1)
    band(y0, y1, x0, min(x0 + width - 1, x1))
    band(y0, y1, max(x1 - width + 1, x0), x1)


def render_nuimage(dataset_or_path, sd_token: str, *, annotation_type: str = "all", with_category: bool = False,
                   with_attributes: bool = False, object_tokens: Sequence[str] | None = None,
                   surface_tokens: Sequence[str] | None = None, render_scale: float = 1.0,
                   box_line_width: int = -1) -> np.ndarray:
    """(H, W, 3) uint8 RGB of image `sd_token` with its annotations (the devkit's `render_image` arguments, without
    `font_size` and `out_path`) (the image is read through the dataset's sensor reader: its `dataroot`)."""
    ds = as_dataset(dataset_or_path)
    if annotation_type not in ANNOTATION_TYPES:
        raise UsageError(f"annotation_type must be one of {', '.join(ANNOTATION_TYPES)}, got {annotation_type!r}")
    if with_attributes and not with_category:
        raise UsageError("with_attributes needs with_category")
    if isinstance(box_line_width, bool) or not isinstance(box_line_width, int):
        raise UsageError(f"box_line_width must be an integer, got {box_line_width!r}")
    if box_line_width == -1:
        box_line_width = int(round(render_scale))
    frame = ds.scan("tables/sample_data").filter(pl.col("token") == sd_token).select(
        "filename", "is_key_frame").collect()
    if frame.height == 0:
        raise UsageError(f"no sample_data {sd_token!r}")
    if not frame["is_key_frame"][0] and (annotation_type != "none" or with_attributes):
        raise UsageError(f"sample_data {sd_token} is not a keyframe: draw it with annotation_type 'none'")
    path = ds.sensors.path(frame["filename"][0])
    image_bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image_bgr is None:
        raise InputError(f"{path}: missing or not an image (sample_data {sd_token})")
    image = np.ascontiguousarray(image_bgr[:, :, ::-1])
    if annotation_type in ("all", "surfaces"):
        surfaces = _chosen(image_annotations(ds, sd_token, "surfaces"), surface_tokens, "surface_tokens")
        for name, mask in zip(surfaces["category_name"].to_list(), decode_rows(surfaces)):
            if mask is not None:
                paste(image, mask, category_rgb(name))
    if annotation_type in ("all", "objects"):
        objects = _chosen(image_annotations(ds, sd_token, "objects", ("bbox", "attribute_names")), object_tokens,
                          "object_tokens")
        for row, mask in zip(objects.iter_rows(named=True), decode_rows(objects)):
            if mask is None:  # the devkit draws neither mask nor box then
                continue
            color = category_rgb(row["category_name"])
            paste(image, mask, color)
            rectangle(image, row["bbox"], color, box_line_width)
            if with_category:
                _label(image, row, with_attributes)
    if render_scale != 1.0:
        h, w = image.shape[:2]
        size = (max(1, int(round(w * render_scale))), max(1, int(round(h * render_scale))))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA if render_scale < 1 else cv2.INTER_LINEAR)
    return image


def _chosen(rows: pl.DataFrame, tokens: Sequence[str] | None, what: str) -> pl.DataFrame:
    """Only `tokens` of `rows` (all when None); UsageError when some are not annotations of this image."""
    if tokens is None:
        return rows
    foreign = sorted(set(tokens) - set(rows["token"].to_list()))
    if foreign:
        raise UsageError(f"{what} {foreign[0]!r} is not an annotation of this image")
    return rows.filter(pl.col("token").is_in(list(tokens)))


def annotation_name(category: str, attributes: Sequence[str], with_attributes: bool) -> str:
    """The devkit's `annotation_name`: the category, then `--` and the attributes joined by dots."""
    return category + ("--" + ".".join(attributes) if with_attributes and attributes else "")


def _label(image: np.ndarray, row: dict, with_attributes: bool) -> None:
    text = annotation_name(row["category_name"], row["attribute_names"] or [], with_attributes)
    x0, y0 = int(row["bbox"][0]), int(row["bbox"][1])
    (_, text_h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
    cv2.putText(image, text, (x0, y0 + text_h), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
