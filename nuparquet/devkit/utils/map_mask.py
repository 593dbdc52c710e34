"""The devkit's `nuscenes.utils.map_mask.MapMask`: a semantic prior map PNG (driveable surface, sidewalks) at a
chosen resolution, and where global x, y fall on it. Read with Pillow and resized with its nearest-neighbour
filter, as the devkit does, so the masks are the devkit's pixel for pixel."""

from __future__ import annotations

import functools
import os.path as osp
from typing import Any

import numpy as np

NATIVE_RESOLUTION_M = 0.1  # metres per pixel of the map PNGs


class MapMask:
    """One map PNG at `resolution` metres per pixel (>= 0.1, the PNGs' own): `mask()`, `is_on_mask(x, y)`,
    `to_pixel_coords(x, y)`, `transform_matrix`. The image is read on first use and kept."""

    def __init__(self, img_file: str, resolution: float = 0.1):
        assert osp.exists(img_file), "map mask {} does not exist".format(img_file)
        assert resolution >= 0.1, "Only supports down to 0.1 meter resolution."
        self.img_file = img_file
        self.resolution = resolution
        self.foreground = 255
        self.background = 0

    def mask(self, dilation: float = 0.0) -> np.ndarray:
        """(H, W) uint8 mask, foreground 255; with `dilation` (metres), every pixel within that distance of the
        foreground too."""
        return _dilated(self, dilation)

    @property
    def transform_matrix(self) -> np.ndarray:
        """(4, 4) pixel_from_global: x / resolution, height - y / resolution."""
        return np.array([[1.0 / self.resolution, 0, 0, 0],
                         [0, -1.0 / self.resolution, 0, self._base_mask.shape[0]],
                         [0, 0, 1, 0], [0, 0, 0, 1]])

    def is_on_mask(self, x: Any, y: Any, dilation: float = 0) -> np.ndarray:
        """(N,) bool: do global x, y (scalars or arrays, metres) fall on the (dilated) foreground?"""
        px, py = self.to_pixel_coords(x, y)
        on_mask = np.ones(px.size, dtype=bool)
        this_mask = self.mask(dilation)
        on_mask[px < 0] = False
        on_mask[px >= this_mask.shape[1]] = False
        on_mask[py < 0] = False
        on_mask[py >= this_mask.shape[0]] = False
        on_mask[on_mask] = this_mask[py[on_mask], px[on_mask]] == self.foreground
        return on_mask

    def to_pixel_coords(self, x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
        """(px, py) int32 pixel columns and rows of global x, y (scalars, lists or 1-D arrays, metres)."""
        x = np.atleast_1d(np.array(x))
        y = np.atleast_1d(np.array(y))
        assert x.shape == y.shape
        assert x.ndim == y.ndim == 1
        pts = np.stack([x, y, np.zeros(x.shape), np.ones(x.shape)])
        pixel_coords = np.round(np.dot(self.transform_matrix, pts)).astype(np.int32)
        return pixel_coords[0, :], pixel_coords[1, :]

    @functools.cached_property
    def _base_mask(self) -> np.ndarray:
        """(H, W) the PNG resized to `resolution` with nearest-neighbour sampling (Pillow, as the devkit)."""
        from PIL import Image

        Image.MAX_IMAGE_PIXELS = 400000 * 400000  # nuScenes' maps are larger than Pillow's default guard
        img = Image.open(self.img_file)
        size_x = int(img.size[0] / self.resolution * NATIVE_RESOLUTION_M)
        size_y = int(img.size[1] / self.resolution * NATIVE_RESOLUTION_M)
        return np.array(img.resize((size_x, size_y), resample=Image.NEAREST))


@functools.lru_cache(maxsize=3)
def _dilated(map_mask: MapMask, dilation: float) -> np.ndarray:
    """The devkit caches three masks (by map and dilation); so does this."""
    base = map_mask._base_mask
    if dilation == 0:
        return base
    import cv2

    distance_mask = cv2.distanceTransform((map_mask.foreground - base).astype(np.uint8), cv2.DIST_L2, 5)
    distance_mask = (distance_mask * map_mask.resolution).astype(np.float32)
    return (distance_mask <= dilation).astype(np.uint8) * map_mask.foreground


class MissingMapMask:
    """Stands in `map['mask']` when the map PNG is not under the dataroot (the devkit's NuScenes refuses to start
    then): the record is readable; using the mask says which file to provide."""

    def __init__(self, img_file: str, resolution: float = 0.1):
        self.img_file = img_file
        self.resolution = resolution
        self.foreground = 255
        self.background = 0

    def _missing(self, *args, **kwargs):
        from nuparquet.devkit.errors import NotServed

        raise NotServed(f"map mask {self.img_file} does not exist: put the map PNGs (maps/*.png) under the dataroot, "
                        "or pass NuScenes(dataroot=...) where they are; the vector maps are nuparquet's "
                        "map/ datasets (nuparquet.map)")

    mask = is_on_mask = to_pixel_coords = _missing

    @property
    def transform_matrix(self):
        self._missing()

    def __repr__(self) -> str:
        return f"<MissingMapMask {self.img_file!r}>"
