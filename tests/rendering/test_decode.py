"""Camera images decoded straight to the tile size (nuparquet.rendering.decode): JPEGs decoded at 1/2, 1/4 or 1/8
by libjpeg's DCT scaling, and refused when their size is not the one their sample_data says."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from nuparquet.rendering.decode import decode_image

EXPECTED_PX = (163, 91)  # (width, height) as sample_data says; odd, so no reduction divides it
TILE = (40, 24)


def _jpeg(folder, width: int, height: int) -> str:
    path = folder / f"{width}x{height}.jpg"
    y, x = np.mgrid[:height, :width]
    assert cv2.imwrite(str(path), np.dstack([x % 256, y % 256, (x + y) % 256]).astype(np.uint8))
    return str(path)


@pytest.mark.parametrize(("scale", "flag"), [(1.0, cv2.IMREAD_COLOR), (0.5, cv2.IMREAD_REDUCED_COLOR_2),
                                             (0.25, cv2.IMREAD_REDUCED_COLOR_4), (0.125, cv2.IMREAD_REDUCED_COLOR_8)])
def test_a_reduced_decode_is_refused_exactly_when_it_is_more_than_one_pixel_off_libjpegs_size_for_the_expected_one(
        tmp_path, scale, flag):
    """libjpeg rounds a reduced size up (ceil(h / 2) rows of an odd h): the size check compares the decoded size
    with that of a file of the expected size decoded the same way (libjpeg's own, the reference here), allowing
    one decoded pixel either way, in each direction."""
    divisor = round(1 / scale)
    reference = cv2.imread(_jpeg(tmp_path, *EXPECTED_PX), flag).shape[:2]  # (rows, cols)
    assert reference == (-(-EXPECTED_PX[1] // divisor), -(-EXPECTED_PX[0] // divisor))  # rounded up
    accepted = refused = 0
    for offset in range(-3 * divisor, 3 * divisor + 1):
        for width, height in ((EXPECTED_PX[0], EXPECTED_PX[1] + offset), (EXPECTED_PX[0] + offset, EXPECTED_PX[1])):
            path = _jpeg(tmp_path, width, height)
            decoded = cv2.imread(path, flag).shape[:2]
            fits = abs(decoded[0] - reference[0]) <= 1 and abs(decoded[1] - reference[1]) <= 1
            got = decode_image(path, TILE, scale, EXPECTED_PX)
            assert (got is not None) == fits, (width, height, decoded, reference)
            if got is not None:
                assert got.shape == (TILE[1], TILE[0], 3)
            accepted, refused = accepted + fits, refused + (not fits)
    assert accepted and refused
    assert decode_image(_jpeg(tmp_path, *EXPECTED_PX), TILE, scale, EXPECTED_PX) is not None
