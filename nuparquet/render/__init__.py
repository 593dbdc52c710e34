"""Boxes and points in camera images: projection (`project`, numpy geometry over polars frames) and drawing
and video encoding built on it. Nothing here reads the nuScenes JSON: the input is the converted Parquet."""
