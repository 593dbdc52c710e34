"""Image files in and out: camera images decoded straight to the tile size, output frames written as images."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def reduced_decode_flag(scale: float) -> tuple[int, int]:
    """The cheapest OpenCV decode mode that still gives at least `scale` of the full size (JPEG DCT scaling):
    (imread flag, size divisor)."""
    for factor, flag in ((8, cv2.IMREAD_REDUCED_COLOR_8), (4, cv2.IMREAD_REDUCED_COLOR_4), (2, cv2.IMREAD_REDUCED_COLOR_2)):
        if scale <= 1.0 / factor:
            return flag, factor
    return cv2.IMREAD_COLOR, 1


def decode_image(path: str, size: tuple[int, int], scale: float) -> np.ndarray | None:
    """Read an image file resized to `size` (width, height), or None if it is missing or not decodable.

    JPEGs are decoded directly at 1/2, 1/4 or 1/8 size when `scale` (output size / file size) allows
    (libjpeg's DCT scaling: several times cheaper than a full decode), then resized with area averaging.
    """
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError:
        return None
    if data.size == 0:
        return None
    flag, _ = reduced_decode_flag(scale)
    image = cv2.imdecode(data, flag)
    if image is None:
        return None
    if image.shape[1] != size[0] or image.shape[0] != size[1]:
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return image


def write_image(path: Path, image_bgr: np.ndarray) -> None:
    """Write an image file (format from the suffix); OSError if OpenCV cannot."""
    if not cv2.imwrite(str(path), image_bgr):
        raise OSError(f"could not write {path}")
