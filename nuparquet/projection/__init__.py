"""Boxes and points in camera images, for many frames at once, exactly as nuscenes-devkit does it.

- `frames`: the camera model (`nuparquet.camera.Cameras`) and sensor poses built once from the stored
  transform columns of `frames` rows.
- `boxes`: `project_boxes` (devkit `get_sample_data` + `view_points` + `box_in_image`), the parity API, and
  the box geometry the renderer shares with it.
- `lidar`: lidar points in camera images (devkit `map_pointcloud_to_image`).

Which boxes a frame shows (devkit `get_boxes`, interpolated for sweeps) is `nuparquet.frame_boxes`.
"""
