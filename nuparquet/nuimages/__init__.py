"""nuImages outputs (`nuparquet convert` of a nuImages dataroot): masks decoded on demand, the devkit's
segmentation masks and its category and attribute counts, from `objects/` and `surfaces/`.

Modules: `masks` (`masks`, the annotations of an image), `segmentation` (`segmentation`, `category_indices`),
`counts` (`category_counts`, `attribute_counts`). Pictures are `nuparquet.rendering.pictures.nuimages`; the COCO file is
`nuparquet.export.coco`.
"""

from __future__ import annotations

# Imported here, not lazily: `masks` and `segmentation` name both a module and its function, and the package's
# names are the functions (a lazy __getattr__ re-entered itself importing the module of the same name).
from nuparquet.nuimages.masks import image_annotations, masks  # noqa: E402
from nuparquet.nuimages.segmentation import category_indices, segmentation  # noqa: E402
from nuparquet.nuimages.counts import attribute_counts, category_counts  # noqa: E402

__all__ = ["attribute_counts", "category_counts", "category_indices", "image_annotations", "masks", "segmentation"]
