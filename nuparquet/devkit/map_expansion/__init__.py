"""nuscenes-devkit's `nuscenes.map_expansion` package over the converted map: `map_api.NuScenesMap`,
`map_api.NuScenesMapExplorer`, `arcline_path_utils`, `bitmap.BitMap`."""
