"""Pictures from the converted Parquet (nothing here reads the nuScenes JSON), in two rooms over the drawing they
share:

- `video/`: the annotated scene video (`video.pipeline.render` one scene, `video.batch.render_scenes` many);
- `pictures/`: one picture of one thing, the devkit's `render_*` (`pictures.single`);
- here, what both draw with: `plan` (the tile protocol: output times, `RowTile`, `TileLoad`), `mosaic` (tile
  placement and the devkit's time matching), `overlay` (every box projected once into the tiles), `points` (lidar
  points per frame), `bev` (the bird's-eye view), `predictions` (a submission's boxes and colours), `draw` (OpenCV
  drawing only), `palette` (the devkit's category colours), `point_colors`, `legend`, `decode`, `map_canvas`.
"""
