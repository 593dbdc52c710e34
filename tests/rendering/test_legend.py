"""Legends and captions drawn into pictures (nuparquet.rendering.legend): a darkened panel in the asked corner,
swatches in the entries' colours and order, names and captions in white, names cut at 25 characters as the devkit's
legend cuts them; the picture untouched outside the panel."""

from __future__ import annotations

import numpy as np

from nuparquet.rendering.legend import PANEL_DARKEN, draw_caption, draw_legend

GREY_BGR = (200, 150, 100)


def _picture(height: int = 240, width: int = 400) -> np.ndarray:
    return np.full((height, width, 3), GREY_BGR, dtype=np.uint8)


def _changed_box(image: np.ndarray) -> tuple[int, int, int, int]:
    """(top, bottom, left, right), bottom and right exclusive, of the pixels that differ from the grey picture."""
    rows, cols = np.nonzero((image != np.array(GREY_BGR, np.uint8)).any(axis=2))
    return rows.min(), rows.max() + 1, cols.min(), cols.max() + 1


def _white(image: np.ndarray) -> np.ndarray:
    return (image == 255).all(axis=-1)


def test_caption_is_white_text_on_a_darkened_band_in_its_corner():
    darkened = (np.array(GREY_BGR) * PANEL_DARKEN).astype(np.uint8)
    for corner in ("bottom-left", "top-right"):
        image = draw_caption(_picture(), "CAM_FRONT_LEFT", corner=corner, font_scale=0.6)
        top, bottom, left, right = _changed_box(image)
        assert (top == 0) == corner.startswith("top") and (bottom == 240) == corner.startswith("bottom"), corner
        assert (left == 0) == corner.endswith("left") and (right == 400) == corner.endswith("right"), corner
        assert 0 < bottom - top < 60 and 0 < right - left < 250, corner
        band = image[top:bottom, left:right].reshape(-1, 3)
        white = _white(band)
        assert white.sum() > 50, corner  # the text, in white (255, 255, 255)
        text = ~(band == darkened).all(axis=1)
        # every other pixel of the band is darkened, or anti-aliased text between the dark band and white
        assert ((band[text] >= darkened) & (band[text] <= 255)).all(), corner
        assert text.sum() < 0.6 * len(band), corner
    assert np.array_equal(draw_caption(_picture(), ""), _picture())


def test_legend_swatches_follow_the_entries_order_with_white_names_and_names_are_cut_at_25_characters():
    entries = [("vehicle.car", (255, 158, 0)), ("flat.driveable_surface", (0, 207, 191)),
               ("human.pedestrian.adult.wheelchair", (0, 0, 230))]
    image = draw_legend(_picture(width=600), entries, corner="top-right", font_scale=0.5)
    top, bottom, left, right = _changed_box(image)
    assert top > 0 and right < 600 and left > 300 and bottom < 120  # top-right, a margin from the edges
    centres = []
    for _, rgb in entries:
        swatch = (image == np.array(rgb[::-1], np.uint8)).all(axis=2)  # drawn in BGR
        assert swatch.sum() > 40, rgb
        rows, cols = np.nonzero(swatch)
        assert rows.max() - rows.min() < 20 and cols.max() < left + 25, rgb  # a square at the panel's left
        centres.append(rows.mean())
    assert centres == sorted(centres) and len(set(centres)) == 3  # top to bottom in the entries' order
    assert _white(image[top:bottom, left + 25:right]).sum() > 100  # the names
    cut = [(name[:25], rgb) for name, rgb in entries]
    assert np.array_equal(image, draw_legend(_picture(width=600), cut, corner="top-right", font_scale=0.5))
    assert np.array_equal(draw_legend(_picture(), []), _picture())


def test_a_name_with_descenders_stays_in_its_row_when_a_wider_name_has_none():
    """Rows are as deep as the deepest name: 'gjpqy' under a wider 'wwww...' (no descender) must not reach the top
    margin of the next row, which holds no ink of any name."""
    entries = [("wwwwwwwwwww", (255, 0, 0)), ("gjpqy", (0, 255, 0)), ("wwwwwwwwwww", (0, 0, 255))]
    image = draw_legend(_picture(), entries, font_scale=0.5)
    swatch_tops = [np.nonzero((image == np.array(rgb[::-1], np.uint8)).all(axis=2))[0].min() for _, rgb in entries]
    step = swatch_tops[1] - swatch_tops[0]
    assert swatch_tops[2] - swatch_tops[1] == step
    darkened = (image == (np.array(GREY_BGR) * PANEL_DARKEN).astype(np.uint8)).all(axis=2)
    rows, cols = np.nonzero(darkened)
    panel = np.zeros(darkened.shape, bool)
    panel[rows.min():rows.max() + 1, cols.min():cols.max() + 1] = True
    ink = panel & ((image > np.array(GREY_BGR) * PANEL_DARKEN + 40).all(axis=2))  # white and anti-aliased text
    for top in swatch_tops[1:]:  # a swatch starts 2 px below its row's top: those rows hold no name's ink
        assert not ink[top - 2:top].any(), top
    # and the descenders of the middle name are drawn within its own row
    rows = np.nonzero(ink[swatch_tops[1] - 2:swatch_tops[2] - 2].any(axis=1))[0]
    assert rows.max() > step * 0.75  # the descenders reach low into the row


def test_the_caption_text_lies_inside_its_darkened_band_in_every_corner():
    """Every pixel the caption changes, its text included, lies within the darkened band's rectangle: text drawn
    too low spills out of a top band (or off the picture under a bottom one)."""
    darkened = (np.array(GREY_BGR) * PANEL_DARKEN).astype(np.uint8)
    for corner in ("top-left", "top-right", "bottom-left", "bottom-right"):
        image = draw_caption(_picture(), "CAM_BACK_RIGHT jpg", corner=corner, font_scale=0.6)
        rows, cols = np.nonzero((image == darkened).all(axis=2))
        band = (rows.min(), rows.max() + 1, cols.min(), cols.max() + 1)
        assert _changed_box(image) == band, corner
        white_rows = np.nonzero(_white(image).any(axis=1))[0]
        assert band[0] + 2 <= white_rows.min() and white_rows.max() < band[1] - 2, corner  # a margin inside the band


def test_a_legend_without_a_corner_sits_top_left():
    """draw_legend's default corner is the top-left one, 6 px in from both edges (the corners asked for sit alike)."""
    entries = [("vehicle.car", (255, 158, 0)), ("flat.driveable_surface", (0, 207, 191))]
    image = draw_legend(_picture(), entries, font_scale=0.5)
    top, bottom, left, right = _changed_box(image)
    assert (top, left) == (6, 6) and bottom < 120 and right < 200
    assert np.array_equal(image, draw_legend(_picture(), entries, corner="top-left", font_scale=0.5))
