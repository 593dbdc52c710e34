"""Masks of a nuImages output decoded on demand, pixel for pixel as the devkit's `mask_decode`
(`nuparquet.rle`: numpy, no pycocotools), and the annotations of one image in the devkit's order."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl

from nuparquet import rle
from nuparquet.errors import UsageError

KINDS = ("objects", "surfaces")  # the datasets holding masks


def check_nuimages(ds) -> None:
    """UsageError unless `ds` is a nuImages conversion."""
    if not all(name in ds.datasets for name in KINDS):
        raise UsageError(f"{ds.root} is not a nuImages conversion (it has no objects/ and surfaces/; convert a "
                         "nuImages dataroot, or name it with --source-format nuimages)")


def masks(ds, tokens: str | Sequence[str]) -> np.ndarray:
    """The masks of object_ann and/or surface_ann `tokens`, in that order: (N, H, W) uint8, 1 inside (one token:
    (H, W)). An annotation without a mask (null in the source) gives zeros. UsageError naming a token that neither
    dataset holds, or when the masks' sizes differ (ask for them apart)."""
    check_nuimages(ds)
    one = isinstance(tokens, str)
    wanted = [tokens] if one else list(tokens)
    columns = ["token", "mask_height", "mask_width", "mask_counts", "height", "width"]
    rows = pl.concat([ds.scan(kind).select(columns).filter(pl.col("token").is_in(wanted)).collect()
                      for kind in KINDS])
    found = dict(zip(rows["token"].to_list(), rows.iter_rows()))
    missing = [t for t in wanted if t not in found]
    if missing:
        raise UsageError(f"no object_ann or surface_ann {missing[0]!r}" + (f" (and {len(missing) - 1} more)"
                                                                          if len(missing) > 1 else ""))
    sizes = {(r[1], r[2]) if r[3] is not None else (r[4], r[5]) for r in (found[t] for t in wanted)}
    if len(sizes) > 1:
        raise UsageError(f"the masks have {len(sizes)} sizes ({', '.join(f'{h}x{w}' for h, w in sorted(sizes))}); "
                         "ask for each size apart")
    height, width = sizes.pop() if sizes else (0, 0)
    out = np.zeros((len(wanted), height, width), np.uint8)
    for i, token in enumerate(wanted):
        counts = found[token][3]
        if counts is not None:
            out[i] = rle.decode({"size": [height, width], "counts": counts})
    return out[0] if one else out


def image_annotations(ds, sd_token: str, kind: str, columns: Sequence[str] = ()) -> pl.DataFrame:
    """The rows of `kind` ("objects" or "surfaces") of image `sd_token`, in their file's order (the devkit's)."""
    check_nuimages(ds)
    base = ["token", "category_name", "mask_height", "mask_width", "mask_counts", "file_index"]
    return (ds.scan(kind).filter(pl.col("sample_data_token") == sd_token)
            .select(*base, *[c for c in columns if c not in base]).sort("file_index").collect())


def decode_rows(rows: pl.DataFrame) -> list[np.ndarray | None]:
    """Each row's mask (None where it has none), from `mask_height`, `mask_width`, `mask_counts`."""
    return [None if counts is None else rle.decode({"size": [h, w], "counts": counts})
            for h, w, counts in rows.select("mask_height", "mask_width", "mask_counts").iter_rows()]
