"""`nuparquet.rle` against pycocotools (test-only): the compressed RLE string both ways, the batch summary, and
the strings it refuses."""

from __future__ import annotations

import base64

import numpy as np
import pytest
from pycocotools import mask as cocomask

from nuparquet import rle


def _masks(seed: int, n: int):
    rng = np.random.default_rng(seed)
    for i in range(n):
        h, w = (int(v) for v in rng.integers(1, 50, 2))
        mask = (rng.random((h, w)) < rng.random()).astype(np.uint8)
        if i % 4 == 0:  # long runs: counts of several 5-bit groups and negative deltas between them
            mask[:] = 0
            mask[int(rng.integers(0, h)):, int(rng.integers(0, w)):] = 1
        if i % 9 == 0:
            mask[:] = i % 2  # all 0 / all 1 (a mask starting with a 1 opens with an empty run)
        yield mask


def test_strings_are_pycocotools_both_ways():
    for mask in _masks(0, 300):
        reference = cocomask.encode(np.asfortranarray(mask))
        ours = rle.encode(mask)
        assert base64.b64decode(ours["counts"]) == reference["counts"]
        assert np.array_equal(rle.decode(ours), cocomask.decode(reference))
        assert rle.area(rle.counts_of(ours)[0]) == cocomask.area(reference)


def test_a_full_size_mask_with_runs_of_six_groups_round_trips():
    mask = np.zeros((900, 1600), np.uint8)
    mask[100:800, 3:1500] = 1
    mask[0, 0] = 1
    reference = cocomask.encode(np.asfortranarray(mask))
    assert base64.b64decode(rle.encode(mask)["counts"]) == reference["counts"]
    assert np.array_equal(rle.decode({"size": [900, 1600], "counts": base64.b64encode(reference["counts"])}), mask)


def test_the_batch_summary_is_each_mask_s_area_and_flags_only_the_bad_ones():
    masks = list(_masks(1, 120))
    texts = [cocomask.encode(np.asfortranarray(m))["counts"] for m in masks]
    heights = [m.shape[0] for m in masks]
    widths = [m.shape[1] for m in masks]
    bad_texts = [b"3", b"\x00", b"2P", b"0" * 1 + b"ooooooo0"]  # short total, NUL, cut number, 8 groups
    areas, bad = rle.summarise(texts + bad_texts, np.array(heights + [1, 1, 1, 1]), np.array(widths + [2, 1, 2, 9]))
    assert areas[:120].tolist() == [int(m.sum()) for m in masks]
    assert not bad[:120].any() and bad[120:].all()


@pytest.mark.parametrize("counts,why", [
    (b"3", "its runs cover 3 pixels"), (b"\x00", "holds the byte 0"), (b"2P", "ends inside a number"),
    (b"ooooooo0", r"of 8 groups \(at most 6\)"),
])
def test_strings_pycocotools_would_misread_are_refused(counts, why):
    with pytest.raises(rle.MaskError, match=why):
        rle.counts_of({"size": [1, 2], "counts": base64.b64encode(counts).decode()})


def test_counts_that_are_not_base64_are_refused():
    with pytest.raises(rle.MaskError, match="not base64"):
        rle.counts_of({"size": [1, 2], "counts": "abc"})
