"""Image files in and out: camera images decoded straight to the tile size, output frames written as images."""

from __future__ import annotations

import os
import stat

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


def decode_image(path: str, size: tuple[int, int], scale: float,
                 expected_px: tuple[int, int] | None = None) -> np.ndarray | None:
    """Read an image file resized to `size` (width, height), or None if it is missing, not a regular file (a named
    pipe would block the read forever), damaged (a JPEG cut short decodes with grey rows: refused), or not of the
    `expected_px` size (width, height) its sample_data says (the intrinsic would not fit it).

    JPEGs are decoded directly at 1/2, 1/4 or 1/8 size when `scale` (output size / file size) allows
    (libjpeg's DCT scaling: several times cheaper than a full decode), then resized with area averaging.
    """
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return None
        data = np.fromfile(path, dtype=np.uint8)
    except OSError:
        return None
    return decode_image_data(data, path, size, scale, expected_px)


def decode_image_data(data: np.ndarray, path: str, size: tuple[int, int], scale: float,
                      expected_px: tuple[int, int] | None = None) -> np.ndarray | None:
    """`decode_image` of a file's bytes (`data`, uint8; `path` names it: its suffix says JPEG)."""
    if data.size == 0:
        return None
    if path.lower().endswith((".jpg", ".jpeg")) and not _jpeg_complete(data):
        return None
    flag, divisor = reduced_decode_flag(scale)
    image = cv2.imdecode(data, flag)
    if image is None:
        return None
    if expected_px is not None and expected_px[0] > 0:
        want = (-(-expected_px[0] // divisor), -(-expected_px[1] // divisor))  # libjpeg rounds reduced sizes up
        if abs(image.shape[1] - want[0]) > 1 or abs(image.shape[0] - want[1]) > 1:
            return None
    if image.shape[1] != size[0] or image.shape[0] != size[1]:
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return image


def _jpeg_complete(data: np.ndarray) -> bool:
    """A JPEG starts with SOI (FF D8) and ends with EOI (FF D9), allowing a little padding after it."""
    if data.size < 4 or data[0] != 0xFF or data[1] != 0xD8:
        return False
    tail = data[-32:].tobytes()
    return b"\xff\xd9" in tail


def write_image(path: Path, image_bgr: np.ndarray) -> None:
    """Write an image file (format from the suffix); OSError if OpenCV cannot."""
    if not cv2.imwrite(str(path), image_bgr):
        raise OSError(f"could not write {path}")


def frame_image(sensors, row: dict, size: tuple[int, int], scale: float) -> np.ndarray:
    """(H, W, 3) BGR: the camera frame `row` (its `frames` row: token, filename, width, height) decoded to `size`
    as `decode_image` does, its bytes read through the dataset's sensor reader (`sensors`: embedded in the output,
    else the file under the dataroot). InputError naming the file when it is missing or unreadable."""
    from nuparquet.errors import InputError

    image, name = decode_frame(sensors, row["token"], row["filename"], size, scale, (row["width"], row["height"]))
    if image is None:
        raise InputError(f"missing or unreadable image file: {name}")
    return image


def decode_frame(sensors, token: str, filename: str, size: tuple[int, int], scale: float,
                 expected_px: tuple[int, int] | None = None) -> tuple[np.ndarray | None, str]:
    """(`decode_image` of a camera frame's bytes read through the sensor reader, or None when they are missing or
    unreadable; where they were looked for)."""
    try:
        data, name = sensors.file_bytes(token, filename, "camera", where=True)
    except OSError as exc:  # MissingSensorData (neither embedded nor a file) too
        return None, getattr(exc, "path", None) or str(exc.filename or filename)
    return decode_image_data(np.frombuffer(data, np.uint8), name, size, scale, expected_px), name
