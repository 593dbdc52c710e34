"""One picture of one thing, the devkit's `render_*` drawn from the Parquet: `single` (the entry points, with
`image_options.ImageOptions`), `sample_data`, `sample_grid`, `annotation`, `pointcloud_image`, `clouds` and
`topview` (a frame, a sample, an annotation, points on an image), `map_views` and `map_in_image` (the map
expansion's pictures), `nuimages` (a nuImages image with its annotations), `charts` (the PNG charts of `stats`)."""
