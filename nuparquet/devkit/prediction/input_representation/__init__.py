"""nuscenes-devkit 1.2.0's `nuscenes.prediction.input_representation`: the prediction models' raster inputs (map
layers, lanes and faded agent boxes) over a `nuparquet.devkit.prediction.PredictHelper`, pixel for pixel, the map
answered by `Dataset.map(location)` (`nuparquet.map.queries.MapLayers`) from the converted output alone."""
