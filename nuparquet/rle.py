"""COCO run-length masks (pycocotools' compressed RLE, as nuImages stores them base64-encoded), in numpy.

A mask of H x W pixels is read column by column (Fortran order) as runs of 0s and 1s, starting with 0s: `counts`
are the run lengths. pycocotools writes them as a string (`rleToString` in its `maskApi.c`): each count, minus
the count two places before it from the fourth on, in 5-bit groups (low first), one character `48 + group` per
group with bit 0x20 saying another group follows and bit 0x10 of the last group carrying the sign. nuImages
base64-encodes that string (`nuimages.utils.utils.mask_decode` undoes it before `pycocotools.mask.decode`).

`counts_from_string` / `counts_to_string` are that code over arrays (no loop per character or run); `decode`
gives the devkit's `mask_decode` pixels, `area` pycocotools' `mask.area`. A string that pycocotools would read
past its end, or whose runs do not cover exactly H x W pixels, is refused (`MaskError`): pycocotools' answer for
it is undefined (it writes past the mask's end), so no conversion may depend on it.
"""

from __future__ import annotations

import base64
import binascii

import numpy as np

MAX_GROUPS = 6  # 6 groups hold +-2**29, beyond any image: more is not a string pycocotools writes for a mask


class MaskError(ValueError):
    """A mask that cannot be decoded exactly (the message says why)."""


def counts_from_string(text: bytes | str) -> np.ndarray:
    """The run lengths (int64) of a compressed RLE string (pycocotools' `rleFrString`)."""
    raw = np.frombuffer(text.encode("ascii") if isinstance(text, str) else bytes(text), np.uint8)
    if len(raw) == 0:
        return np.zeros(0, np.int64)
    if raw.min() < 48 or raw.max() > 111:  # a character outside the 64 codes (NUL ends pycocotools' string early)
        bad = int(raw[(raw < 48) | (raw > 111)][0])
        raise MaskError(f"the RLE string holds the byte {bad}, not one of the 64 characters '0'..'o'")
    c = raw.astype(np.int64) - 48
    last = (c & 0x20) == 0  # the last group of a number
    if not last[-1]:
        raise MaskError("the RLE string ends inside a number")
    ends = np.flatnonzero(last)
    starts = np.concatenate([[0], ends[:-1] + 1])
    lengths = ends - starts + 1
    if lengths.max() > MAX_GROUPS:
        raise MaskError(f"the RLE string holds a number of {int(lengths.max())} groups (at most {MAX_GROUPS})")
    position = np.arange(len(c)) - np.repeat(starts, lengths)  # the group's place in its number
    x = np.add.reduceat((c & 0x1F) << (5 * position), starts)
    negative = (c[ends] & 0x10) != 0
    x = np.where(negative, x | (-1 << (5 * lengths)), x)
    counts = x.copy()
    # from the fourth count on, each is stored as the difference to the one two before (index 2 is not)
    if len(counts) > 3:
        counts[3::2] = np.cumsum(np.concatenate([[counts[1]], x[3::2]]))[1:]
    if len(counts) > 4:
        counts[4::2] = np.cumsum(np.concatenate([[counts[2]], x[4::2]]))[1:]
    return counts


def counts_to_string(counts: np.ndarray) -> bytes:
    """The compressed RLE string of run lengths `counts` (pycocotools' `rleToString`)."""
    counts = np.asarray(counts, np.int64)
    x = counts.copy()
    if len(x) > 3:
        x[3:] -= counts[1:-2]
    groups = np.zeros((len(x), MAX_GROUPS + 1), np.int64)
    more = np.zeros_like(groups, bool)
    value = x.copy()
    alive = np.ones(len(x), bool)  # numbers still writing groups
    for g in range(groups.shape[1]):  # a loop over the (at most 7) groups of a number, not over runs
        c = value & 0x1F
        value = value >> 5
        more_here = np.where((c & 0x10) != 0, value != -1, value != 0)
        groups[:, g] = np.where(alive, c | np.where(more_here, 0x20, 0), -1)
        more[:, g] = alive & more_here
        alive = more[:, g]
    flat = groups.ravel()
    return (flat[flat >= 0] + 48).astype(np.uint8).tobytes()


def counts_of(mask: dict) -> tuple[np.ndarray, int, int]:
    """(run lengths, height, width) of a nuImages mask `{"size": [h, w], "counts": base64 text}`, checked: the runs
    cover exactly h x w pixels."""
    height, width = (int(v) for v in mask["size"])
    try:
        text = base64.b64decode(mask["counts"])  # as the devkit's mask_decode (not validate=True: the same bytes)
    except (binascii.Error, ValueError) as exc:
        raise MaskError(f"its counts are not base64 ({exc})") from exc
    counts = counts_from_string(text)
    check_counts(counts, height, width)
    return counts, height, width


def check_counts(counts: np.ndarray, height: int, width: int) -> None:
    if height < 0 or width < 0:
        raise MaskError(f"its size {[height, width]} is negative")
    if len(counts) and counts.min() < 0:
        raise MaskError(f"a run of {int(counts.min())} pixels")
    total = int(counts.sum())
    if total != height * width:
        raise MaskError(f"its runs cover {total:,} pixels, its size {height} x {width} = {height * width:,}")


def decode_counts(counts: np.ndarray, height: int, width: int) -> np.ndarray:
    """(height, width) uint8 0/1 from run lengths (0s first, column by column)."""
    values = (np.arange(len(counts)) % 2).astype(np.uint8)
    return np.repeat(values, counts).reshape(width, height).T


def decode(mask: dict) -> np.ndarray:
    """A nuImages mask as the devkit's `mask_decode` gives it: (h, w) uint8, 1 inside."""
    counts, height, width = counts_of(mask)
    return decode_counts(counts, height, width)


def area(counts: np.ndarray) -> int:
    """Pixels inside (the odd runs): pycocotools' `mask.area`."""
    return int(np.asarray(counts)[1::2].sum())


def summarise(texts: list[bytes], heights: np.ndarray, widths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(area (N,) int64, bad (N,) bool) of N compressed RLE strings at once (one pass over all their bytes, no loop
    per mask): `bad` where `counts_of` would refuse the string (then the area is meaningless); `counts_of` on one of
    them says why."""
    n = len(texts)
    lengths = np.fromiter(map(len, texts), np.int64, n)
    blob = np.frombuffer(b"".join(texts), np.uint8)
    bad = np.zeros(n, bool)
    if len(blob) == 0:
        return np.zeros(n, np.int64), bad | (np.asarray(heights) * np.asarray(widths) != 0)
    owner = np.repeat(np.arange(n), lengths)  # the mask of each byte
    wrong_char = (blob < 48) | (blob > 111)
    bad[owner[wrong_char]] = True
    c = (blob.astype(np.int64) - 48) & 0x3F
    last = (c & 0x20) == 0
    ends_of_masks = np.cumsum(lengths)[lengths > 0] - 1
    bad[owner[ends_of_masks[~last[ends_of_masks]]]] = True  # the string ends inside a number
    last[ends_of_masks] = True  # numbers never run from one mask into the next
    ends = np.flatnonzero(last)
    starts = np.concatenate([[0], ends[:-1] + 1])
    groups = ends - starts + 1
    bad[owner[ends[groups > MAX_GROUPS]]] = True
    groups = np.minimum(groups, MAX_GROUPS)
    position = np.minimum(np.arange(len(c)) - np.repeat(starts, ends - starts + 1), MAX_GROUPS - 1)
    x = np.add.reduceat((c & 0x1F) << (5 * position), starts)
    x = np.where((c[ends] & 0x10) != 0, x | (-1 << (5 * groups)), x)
    mask_of = owner[ends]
    first = np.searchsorted(mask_of, np.arange(n))  # each mask's first number
    j = np.arange(len(x)) - first[mask_of]  # the number's place in its mask
    # from the fourth count on, each is the difference to the one two before: cumulative sums along three chains
    # per mask (index 0 alone; 1, 3, 5, ...; 2, 4, 6, ...), one segmented cumulative sum for all masks
    chain = np.where(j == 0, 0, np.where(j % 2 == 1, 1, 2))
    order = np.lexsort((j, chain, mask_of))
    running = np.cumsum(x[order])
    key = mask_of[order] * 3 + chain[order]
    new = np.concatenate([[True], key[1:] != key[:-1]])
    base = np.maximum.accumulate(np.where(new, np.arange(len(key)), 0))
    before = np.concatenate([[0], running])[base]
    counts = np.empty_like(x)
    counts[order] = running - before
    bad[mask_of[counts < 0]] = True
    total = np.bincount(mask_of, weights=counts, minlength=n)
    inside = np.bincount(mask_of[j % 2 == 1], weights=counts[j % 2 == 1], minlength=n)
    bad |= total != np.asarray(heights, np.float64) * np.asarray(widths, np.float64)
    return inside.astype(np.int64), bad


def encode(mask: np.ndarray) -> dict:
    """A (h, w) 0/1 mask as nuImages stores it: `{"size": [h, w], "counts": base64 of the RLE string}`."""
    flat = np.asarray(mask, bool).T.ravel()
    changes = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    bounds = np.concatenate([[0], changes, [len(flat)]])
    runs = np.diff(bounds)
    if len(flat) and flat[0]:
        runs = np.concatenate([[0], runs])
    return {"size": [int(mask.shape[0]), int(mask.shape[1])],
            "counts": base64.b64encode(counts_to_string(runs)).decode("ascii")}
