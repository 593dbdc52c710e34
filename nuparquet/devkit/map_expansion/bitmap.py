"""The devkit's `nuscenes.map_expansion.bitmap.BitMap`: a map's raster layer under the vector layers of a render.

The PNGs are not converted (they are pictures, not records): `BitMap` reads them where the devkit does, under the
dataroot (`NuScenesMap.dataroot`: the one the output was converted from, or the one given), and says which file is
missing as the devkit does.
"""

from __future__ import annotations

import os
from typing import Any, Tuple

import numpy as np

Axis = Any

SEMANTIC_PRIOR_HASHES = {  # the devkit's file names of nuScenes v1.0's semantic prior masks
    'singapore-onenorth': '53992ee3023e5494b90c316c183be829',
    'singapore-hollandvillage': '37819e65e09e5547b8a3ceaefba56bb2',
    'singapore-queenstown': '93406b464a165eaba6d9de76ca09f5da',
    'boston-seaport': '36092f0b03a857c6a3403e25b4b7aab3',
}


class BitMap:
    """A bitmap layer of a map: `basemap` (the lidar basemap, `maps/basemap/<map>.png`) or `semantic_prior`
    (nuScenes v1.0's drivable surface and sidewalks, `maps/<hash>.png`, colours inverted)."""

    def __init__(self, dataroot: str, map_name: str, layer_name: str):
        self.dataroot = dataroot
        self.map_name = map_name
        self.layer_name = layer_name

        self.image = self.load_bitmap()

    def load_bitmap(self) -> np.ndarray:
        """The bitmap as a numpy array (Pillow)."""
        from PIL import Image

        if self.layer_name == 'basemap':
            map_path = os.path.join(self.dataroot, 'maps', 'basemap', self.map_name + '.png')
        elif self.layer_name == 'semantic_prior':
            map_path = os.path.join(self.dataroot, 'maps', SEMANTIC_PRIOR_HASHES[self.map_name] + '.png')
        else:
            raise Exception('Error: Invalid bitmap layer: %s' % self.layer_name)

        if os.path.exists(map_path):
            image = np.array(Image.open(map_path))
        else:
            raise Exception('Error: Cannot find %s %s! Please make sure that the map is correctly installed.'
                            % (self.layer_name, map_path))

        # Invert semantic prior colors.
        if self.layer_name == 'semantic_prior':
            image = image.max() - image

        return image

    def render(self, canvas_edge: Tuple[float, float], ax: Axis = None):
        """Draw the bitmap over the whole map's extent (`canvas_edge`, metres) on `ax` (default a new subplot)."""
        from nuparquet.devkit.map_expansion.map_renders import _pyplot

        if ax is None:
            ax = _pyplot().subplot()
        x, y = canvas_edge
        if len(self.image.shape) == 2:
            ax.imshow(self.image, extent=[0, x, 0, y], cmap='gray')
        else:
            ax.imshow(self.image, extent=[0, x, 0, y])
