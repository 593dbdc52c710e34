"""The annotated scene video, cut by stage: `options` (`RenderOptions`, `SceneSelection`, the CLI flags),
`pipeline.render` (one scene) and `batch.render_scenes` (many, through the engine), `scene` (the one query and the
cameras shown), `camera_tile` and `bev_scene` (the tile sources), `loop` (the frame loop), `sink`, `video` and
`frame_index` (where the pictures go: H.264, PNG frames and their index)."""
