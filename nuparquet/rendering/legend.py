"""Legends and captions drawn into pictures (OpenCV): a panel of colour swatches with names (lidarseg classes, map
layers), and a caption naming the picture (a channel, "predictions"). The devkit puts these beside the axes
(matplotlib legends and titles); here they sit in a corner of the picture, on a darkened panel.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from nuparquet.rendering.draw import TEXT_FONT, rgb_to_bgr

MAX_NAME_CHARS = 25  # the devkit's create_lidarseg_legend truncates class names to 25 characters
PANEL_DARKEN = 0.35


def _font_scale(image: np.ndarray) -> float:
    return max(0.35, min(image.shape[:2]) / 1500)


def draw_legend(image_bgr: np.ndarray, entries: Sequence[tuple[str, Sequence]], *, corner: str = "top-left",
                font_scale: float | None = None, max_chars: int = MAX_NAME_CHARS) -> np.ndarray:
    """A panel of (name, RGB) swatches in a corner ("top-left", "top-right", "bottom-left", "bottom-right"), in place;
    nothing for no entries. Names longer than 25 characters are cut, as the devkit's legend cuts them. An entry's
    colour may be a sequence of RGB colours (a swatch of stripes: "one colour per track")."""
    if not entries:
        return image_bgr
    font = font_scale or _font_scale(image_bgr)
    thickness = max(1, round(font * 1.5))
    names = [name[:max_chars] for name, _ in entries]
    # every row as tall as the tallest name and as deep as the deepest descender (g, j, p, q, y), so no name
    # reaches into the next row whichever name is the widest
    sizes = [cv2.getTextSize(n, TEXT_FONT, font, thickness) for n in names]
    text_w, text_h = max(w for (w, _), _ in sizes), max(h for (_, h), _ in sizes)
    baseline = max(b for _, b in sizes)
    step = text_h + baseline + 6
    panel_w, panel_h = step + 8 + text_w + 8, step * len(entries) + 8
    height, width = image_bgr.shape[:2]
    x = 6 if corner.endswith("left") else max(0, width - panel_w - 6)
    y = 6 if corner.startswith("top") else max(0, height - panel_h - 6)
    region = image_bgr[y:y + panel_h, x:x + panel_w]
    region[:] = (region * PANEL_DARKEN).astype(np.uint8)
    for i, (name, (_, rgb)) in enumerate(zip(names, entries)):
        top = y + 4 + i * step
        stripes = [rgb] if np.ndim(rgb) == 1 else list(rgb)
        edges = np.linspace(x + 4, x + step, len(stripes) + 1).round().astype(int)
        for left, right, stripe in zip(edges[:-1], edges[1:], stripes):
            colour = tuple(int(c) for c in rgb_to_bgr(stripe))
            cv2.rectangle(image_bgr, (int(left), top + 2), (int(right), top + step - 2), colour, cv2.FILLED)
        cv2.putText(image_bgr, name, (x + step + 6, top + step - baseline - 3), TEXT_FONT, font, (255, 255, 255),
                    thickness, cv2.LINE_AA)
    return image_bgr


def draw_caption(image_bgr: np.ndarray, text: str, *, corner: str = "bottom-left",
                 font_scale: float | None = None) -> np.ndarray:
    """`text` in white on a darkened band in a corner of the picture, in place."""
    if not text:
        return image_bgr
    font = font_scale or _font_scale(image_bgr)
    thickness = max(1, round(font * 1.5))
    (text_w, text_h), baseline = cv2.getTextSize(text, TEXT_FONT, font, thickness)
    height, width = image_bgr.shape[:2]
    box_w, box_h = text_w + 10, text_h + baseline + 10
    x = 0 if corner.endswith("left") else max(0, width - box_w)
    y = 0 if corner.startswith("top") else max(0, height - box_h)
    region = image_bgr[y:y + box_h, x:x + box_w]
    region[:] = (region * PANEL_DARKEN).astype(np.uint8)
    cv2.putText(image_bgr, text, (x + 5, y + box_h - baseline - 5), TEXT_FONT, font, (255, 255, 255), thickness,
                cv2.LINE_AA)
    return image_bgr
