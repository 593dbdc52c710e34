"""nuImages outputs (`nuparquet convert` of a nuImages dataroot): masks decoded on demand, the devkit's
segmentation masks and its category and attribute counts, from `objects/` and `surfaces/`.

Modules: `masks` (`masks`, the annotations of an image), `segmentation` (`segmentation`, `category_indices`),
`counts` (`category_counts`, `attribute_counts`). Pictures are `nuparquet.rendering.pictures.nuimages`; the COCO file is
`nuparquet.export.coco`.
"""

from __future__ import annotations

__all__ = ["attribute_counts", "category_counts", "category_indices", "masks", "segmentation"]


def __getattr__(name: str):
    if name in ("masks", "image_annotations"):
        from nuparquet.nuimages import masks as module
    elif name in ("segmentation", "category_indices"):
        from nuparquet.nuimages import segmentation as module
    elif name in ("category_counts", "attribute_counts"):
        from nuparquet.nuimages import counts as module
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(module, name)
