"""Annotated scene videos from the converted Parquet, cut by stage (nothing here reads the nuScenes JSON):

- `options`: what a render can be asked (`RenderOptions`, also the CLI flags); `pipeline.render` runs it.
- `scene`: the one query (camera frames, annotations, samples, lidar keyframes) and the cameras to show.
- `plan`: output times and the tile sources of each picture (`TileSource`: `camera_tile.CameraTile` today,
  a bird's-eye view later); `mosaic`: tile placement and the devkit's time matching.
- `overlay`: every box projected once into the tiles (`nuparquet.geometry.camera`); `points`: lidar points per tile.
- `decode`, `loop`, `sink`, `video`: image decoding, the frame loop, and where pictures are written.
- `draw`: OpenCV drawing only.
"""
