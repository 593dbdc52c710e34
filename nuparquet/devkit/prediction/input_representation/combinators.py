"""The devkit's `input_representation.combinators`: images overlaid without mixing colours (the last image whose
pixel is not black in OpenCV's grey wins), with the devkit's OpenCV calls, so the bits are its bits."""

from __future__ import annotations

from functools import reduce

import cv2
import numpy as np

from nuparquet.devkit.prediction.input_representation.interface import Combinator


def add_foreground_to_image(base_image: np.ndarray, foreground_image: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 `base_image` with the pixels of `foreground_image` whose grey value is not 0 on top.

    Raises:
        ValueError: the shapes differ, or either image is not uint8 (the devkit's messages).
    """
    if not base_image.shape == foreground_image.shape:
        raise ValueError("base_image and foreground image must have the same shape."
                         f" Received {base_image.shape} and {foreground_image.shape}")
    if not (base_image.dtype == "uint8" and foreground_image.dtype == "uint8"):
        raise ValueError("base_image and foreground image must be of type 'uint8'."
                         f" Received {base_image.dtype} and {foreground_image.dtype}")
    # grey 0 counts as background: a dark colour such as (0, 0, 1) is not drawn (OpenCV's grey rounds it to 0)
    img2gray = cv2.cvtColor(foreground_image, cv2.COLOR_BGR2GRAY)
    _, mask = cv2.threshold(img2gray, 0, 255, cv2.THRESH_BINARY)
    mask_inv = cv2.bitwise_not(mask)
    img1_bg = cv2.bitwise_and(base_image, base_image, mask=mask_inv)
    img2_fg = cv2.bitwise_and(foreground_image, foreground_image, mask=mask)
    return cv2.add(img1_bg, img2_fg)


class Rasterizer(Combinator):
    """Combines three-channel images into one, later images on top."""

    def combine(self, data: list[np.ndarray]) -> np.ndarray:
        """(H, W, 3) uint8: `data` (each (H, W, 3) uint8) overlaid in order on black."""
        base_image = np.zeros(data[0].shape).astype("uint8")
        return reduce(add_foreground_to_image, [base_image] + data)
