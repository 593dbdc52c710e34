"""The devkit's segmentation masks of one nuImages image (`NuImages.get_segmentation`) and its class indices
(`nuimages.utils.utils.name_to_index_mapping`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl

from nuparquet.errors import InputError, UsageError
from nuparquet.nuimages.masks import check_nuimages, decode_rows, image_annotations

DRIVEABLE, EGO = "flat.driveable_surface", "vehicle.ego"
DRIVEABLE_INDEX, EGO_INDEX = 24, 31
MAX_OBJECT_CLASSES = 23


def category_indices(names: Sequence[str]) -> dict[str, int]:
    """name -> class index as the devkit numbers them: the categories other than the two surfaces by name from 1,
    then flat.driveable_surface 24 and vehicle.ego 31 (0 is the background). InputError when the taxonomy has more
    than 23 other classes (the devkit's assertion)."""
    others = sorted(n for n in names if n not in (DRIVEABLE, EGO))
    if len(others) > MAX_OBJECT_CLASSES:
        raise InputError(f"category.json has {len(others)} classes besides {DRIVEABLE} and {EGO}; the devkit's "
                         f"segmentation indices allow {MAX_OBJECT_CLASSES}")
    indices = {name: i for i, name in enumerate(others, start=1)}
    return indices | {DRIVEABLE: DRIVEABLE_INDEX, EGO: EGO_INDEX}


def segmentation(ds, sd_token: str) -> tuple[np.ndarray, np.ndarray]:
    """(semantic, instance) (H, W) int32 masks of keyframe image `sd_token`, as `NuImages.get_segmentation`: the
    surfaces painted with their class index in file order, then the objects sorted by token, each painting its
    class index and its place from 1 in that order (objects without a mask keep their place and paint nothing).
    H, W are the image's size as sample_data gives it (the devkit opens the JPEG to learn it)."""
    check_nuimages(ds)
    image = ds.scan("tables/sample_data").filter(pl.col("token") == sd_token).select(
        "is_key_frame", "height", "width").collect()
    if image.height == 0:
        raise UsageError(f"no sample_data {sd_token!r}")
    if not image["is_key_frame"][0]:
        raise UsageError(f"sample_data {sd_token} is not a keyframe: only keyframes are annotated")
    indices = category_indices(ds.scan("tables/category").select("name").collect()["name"].to_list())
    height, width = int(image["height"][0]), int(image["width"][0])
    semantic = np.zeros((height, width), np.int32)
    instance = np.zeros((height, width), np.int32)
    surfaces = image_annotations(ds, sd_token, "surfaces")
    for name, mask in zip(surfaces["category_name"].to_list(), decode_rows(surfaces)):
        if mask is not None:
            semantic[mask == 1] = indices[name]
    objects = image_annotations(ds, sd_token, "objects").sort("token")
    for i, (name, mask) in enumerate(zip(objects["category_name"].to_list(), decode_rows(objects)), start=1):
        if mask is not None:
            semantic[mask == 1] = indices[name]
            instance[mask == 1] = i
    return semantic, instance
