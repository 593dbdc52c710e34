"""Annotated scene videos and pictures from the converted Parquet, cut by stage (nothing here reads the nuScenes
JSON):

- `options`: what a render can be asked (`RenderOptions`, `SceneSelection`, also the CLI flags); `pipeline.render`
  runs one scene, `batch.render_scenes` many through the engine.
- `scene`: the one query (camera frames, annotations, samples, lidar keyframes) and the cameras to show.
- `plan`: output times and the tile sources of each picture (`TileSource`: `camera_tile.CameraTile`,
  `bev.BevTile`); `mosaic`: tile placement and the devkit's time matching.
- `overlay`: every box projected once into the tiles (`nuparquet.geometry.camera`); `points`: lidar points per tile;
  `bev`, `bev_scene`: the bird's-eye view.
- `decode`, `loop`, `sink`, `video`: image decoding, the frame loop, and where pictures are written.
- `draw`: OpenCV drawing only; `palette`: the devkit's category colours; `charts`: the PNG charts of `stats`.
"""
