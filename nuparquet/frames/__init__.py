"""Work on frames (rows of the `frames` dataset), many at once: where each sensor was (`poses`), which boxes a
frame shows at its own time (`boxes`, devkit `get_boxes`), boxes in camera images (`projection`, devkit
`get_sample_data` + `box_in_image`), sensor points in a camera image (`points_in_image`, devkit
`map_pointcloud_to_image`) and the stored points of chosen frames (`points`); and the annotations' prev/next
chains an agent's past or future is walked along (`annotation_chains`, devkit `PredictHelper`).

The numbers come from `nuparquet.geometry`; this package adds the polars side: which rows, joined how.
"""
