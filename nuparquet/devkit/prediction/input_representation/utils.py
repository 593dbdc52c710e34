"""The devkit's `input_representation.utils`: global coordinates to pixels, the crop that places the agent, and
the image rotation that turns its heading up; each as the devkit computes it (the raster's pixels depend on every
truncation), with array forms where the rasterizers convert many points at once."""

from __future__ import annotations

import cv2
import numpy as np

from nuparquet.devkit.prediction.helper import angle_of_rotation


def pixel_coords(x: np.ndarray, y: np.ndarray, center_of_image_in_global: tuple[float, float],
                 center_of_image_in_pixels: tuple[float, float], resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """(N,) int64 rows and (N,) columns of global (N,) x, y: `convert_to_pixel_coords` for every point (rows grow
    as y falls; Python's `int` truncates toward zero, as `np.trunc` does)."""
    x_pixel = (x - center_of_image_in_global[0]) / resolution
    y_pixel = -(y - center_of_image_in_global[1]) / resolution
    rows = np.trunc(center_of_image_in_pixels[0] + y_pixel).astype(np.int64)
    columns = np.trunc(center_of_image_in_pixels[1] + x_pixel).astype(np.int64)
    return rows, columns


def convert_to_pixel_coords(location: tuple[float, float], center_of_image_in_global: tuple[float, float],
                            center_of_image_in_pixels: tuple[float, float],
                            resolution: float = 0.1) -> tuple[int, int]:
    """(row, column) of a global (x, y) in an image whose centre (row, column) pixel is at
    `center_of_image_in_global`, `resolution` meters per pixel."""
    rows, columns = pixel_coords(np.array([location[0]], np.float64), np.array([location[1]], np.float64),
                                 center_of_image_in_global, center_of_image_in_pixels, resolution)
    return int(rows[0]), int(columns[0])


def get_crops(meters_ahead: float, meters_behind: float, meters_left: float, meters_right: float,
              resolution: float, image_side_length_pixels: int) -> tuple[slice, slice]:
    """The row and column slices that crop the rotated square image to the agent's window (ahead is up)."""
    row_crop = slice(0, int((meters_ahead + meters_behind) / resolution))
    col_crop = slice(int(image_side_length_pixels / 2 - (meters_left / resolution)),
                     int(image_side_length_pixels / 2 + (meters_right / resolution)))
    return row_crop, col_crop


def get_rotation_matrix(image_shape: tuple[int, int, int], yaw_in_radians: float) -> np.ndarray:
    """(2, 3) OpenCV rotation about the image centre that turns `yaw_in_radians` to point up the image."""
    rotation_in_degrees = angle_of_rotation(yaw_in_radians) * 180 / np.pi
    return cv2.getRotationMatrix2D((image_shape[1] / 2, image_shape[0] / 2), rotation_in_degrees, 1)


def rotate_and_crop(image: np.ndarray, yaw_in_radians: float, row_crop: slice, col_crop: slice) -> np.ndarray:
    """`cv2.warpAffine(image, get_rotation_matrix(image.shape, yaw), (W, H))[row_crop, col_crop]` as uint8, the
    warp asked only for the pixels up to the crop's far corner: OpenCV computes each output pixel from its own
    (x, y) alone, so these pixels are the full warp's (the test compares whole rasters with the devkit's)."""
    rows, columns = range(image.shape[0])[row_crop], range(image.shape[1])[col_crop]
    if not len(rows) or not len(columns):
        return np.zeros(image.shape, np.uint8)[row_crop, col_crop]
    rotated = cv2.warpAffine(image, get_rotation_matrix(image.shape, yaw_in_radians), (columns[-1] + 1, rows[-1] + 1))
    return rotated[rows.start:, columns.start:].astype("uint8")
