"""Masks as nuImages stores them (base64 of pycocotools' compressed RLE string), re-implemented on purpose.

The generator is a producer of input like any real dataset (it never imports the library), so it encodes its
masks itself: written from pycocotools' `rleEncode` and `rleToString` (`maskApi.c`) and checked in the tests
against pycocotools and `nuimages.utils.utils.mask_decode`, it is an independent expectation for
`nuparquet.rle`'s decoder rather than a copy of it.
"""

from __future__ import annotations

import base64

import numpy as np


def runs(mask: np.ndarray) -> list[int]:
    """Run lengths of a (h, w) 0/1 mask read column by column, starting with a run of 0s (maybe empty)."""
    flat = np.asarray(mask, bool).T.reshape(-1)
    out, current, length = [], False, 0
    edges = np.flatnonzero(np.diff(flat.astype(np.int8))) + 1  # where the value changes
    start = 0
    for edge in [*edges.tolist(), len(flat)]:
        value = bool(flat[start]) if start < len(flat) else False
        if value != current:  # (only at the very start: a mask whose first pixel is 1 opens with 0 zeros)
            out.append(length)
            length, current = 0, value
        length += edge - start
        out.append(length)
        length, current, start = 0, not current, edge
    return out


def rle_string(counts: list[int]) -> bytes:
    """pycocotools' `rleToString`: deltas from the fourth count on, 5-bit groups, '0' + group, 0x20 = more."""
    chars = bytearray()
    for i, count in enumerate(counts):
        x = count - counts[i - 2] if i > 2 else count
        more = True
        while more:
            c = x & 0x1F
            x >>= 5
            more = (x != -1) if (c & 0x10) else (x != 0)
            chars.append((c | 0x20 if more else c) + 48)
    return bytes(chars)


def encode(mask: np.ndarray) -> dict:
    """`{"size": [h, w], "counts": base64 text}`, the `mask` of an object_ann or surface_ann record."""
    return {"size": [int(mask.shape[0]), int(mask.shape[1])],
            "counts": base64.b64encode(rle_string(runs(mask))).decode("ascii")}
