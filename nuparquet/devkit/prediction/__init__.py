"""nuscenes-devkit's `nuscenes.prediction` package: `helper.PredictHelper` over the converted tables."""

from nuparquet.devkit.prediction.helper import (PredictHelper, convert_global_coords_to_local,
                                                convert_local_coords_to_global)

__all__ = ["PredictHelper", "convert_global_coords_to_local", "convert_local_coords_to_global"]
