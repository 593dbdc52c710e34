"""The boxes each frame shows, in the frame's own coordinates, for many frames at once: what the devkit's
`get_sample_data(token, box_vis_level)` returns (boxes in the sensor frame, camera boxes filtered by
`box_in_image`), in the ego frame at the frame's time, or in the global frame (`get_boxes`).

```python
boxes = boxes_at(frames, ds.scan("annotations"), ds.scan("tables/sample"), visibility="any", at="sensor")
```
(`Dataset.boxes(frames)` finds the annotations and samples itself.)
"""

from __future__ import annotations

from dataclasses import replace
from typing import Literal

import numpy as np
import polars as pl

from nuparquet import columns
from nuparquet.frames.boxes import FRAME_COLUMNS, frame_boxes, lazy_with
from nuparquet.frames.poses import CAMERA_COLUMNS, POSE_COLUMNS, cameras_from_frames, pose_columns
from nuparquet.frames.projection import VISIBILITIES, Visibility, boxes_in_cameras
from nuparquet.geometry import (
    box_visibility, invert_quaternions, multiply_quaternions, perspective, rotation_matrices,
)

Frame = Literal["global", "ego", "sensor"]
FRAMES: tuple[str, ...] = ("global", "ego", "sensor")  # each one step further from the world


def boxes_at(frames: pl.DataFrame | pl.LazyFrame, annotations: pl.DataFrame | pl.LazyFrame,
             samples: pl.DataFrame | pl.LazyFrame, *, visibility: Visibility = "any",
             at: Frame = "sensor") -> pl.DataFrame:
    """One row per (frame, box), ordered by frame then annotation, as the devkit's `get_sample_data` per frame.

    Every frame gets the boxes `frame_boxes` gives it (its sample's annotations, interpolated for sweeps). Camera
    frames (rows with an intrinsic) keep those `box_in_image` keeps at `visibility` ("any", "all", "none":
    BoxVisibility.ANY / ALL / NONE); other sensors keep every box, as the devkit does. Each box is moved as the
    devkit moves a `Box` (translate by -t, rotate by the inverse quaternion): global -> ego with the ego pose at
    the frame's own timestamp -> sensor (its calibration), and reported in the frame `at` asks for.

    Args:
        frames: rows of `frames`: token, sample_token, timestamp, is_key_frame, the poses (ego_translation,
            ego_rotation, sensor_translation, sensor_rotation), camera_intrinsic, width, height.
        annotations, samples: as for `nuparquet.frames.boxes.frame_boxes`.

    Returns:
        frame_index (u32, row of `frames`), frame_token, annotation_token, instance_token, category_name,
        translation (m), size ([w, l, h] m), rotation ([w, x, y, z]) in the frame `at` names, interpolated.
    """
    if visibility not in VISIBILITIES:
        raise ValueError(f"visibility must be one of {', '.join(VISIBILITIES)}, got {visibility!r}")
    if at not in FRAMES:
        raise ValueError(f"at must be one of {', '.join(FRAMES)}, got {at!r}")
    lazy = frames.lazy()
    names = lazy.collect_schema().names()
    needed = FRAME_COLUMNS + CAMERA_COLUMNS + tuple(dict.fromkeys(pose_columns(names) + POSE_COLUMNS))
    rows = lazy_with(lazy, needed, "frames").select(needed).collect()
    boxes = frame_boxes(rows, annotations, samples)
    keep = np.ones(len(boxes), dtype=bool)
    is_camera = rows["camera_intrinsic"].is_not_null().to_numpy()
    seen_by_camera = is_camera[boxes.frame_index]
    if visibility != "none" and seen_by_camera.any():
        camera_rows = np.flatnonzero(is_camera)
        cameras = cameras_from_frames(rows[camera_rows])
        camera_of_box = np.searchsorted(camera_rows, boxes.frame_index[seen_by_camera])
        seen = boxes_in_cameras(cameras, replace(boxes.take(seen_by_camera), frame_index=camera_of_box))
        corners_px, depths = perspective(cameras.image_from_camera[camera_of_box], seen.corners_camera_m)
        corner_visible, in_front, visible = box_visibility(corners_px, depths, cameras.size_px[camera_of_box],
                                                           cameras.scale[camera_of_box])
        if visibility == "all":
            visible = corner_visible.all(axis=1) & in_front
        keep[seen_by_camera] = visible
    boxes = boxes.take(keep)
    translation, rotation = boxes.translation_m, boxes.rotation_wxyz
    frame = boxes.frame_index
    for step in ("ego", "sensor")[:FRAMES.index(at)]:  # global -> ego -> sensor, as far as `at` asks
        t = columns.to_numpy(rows[f"{step}_translation"], (3,))[frame]
        q = columns.to_numpy(rows[f"{step}_rotation"], (4,))[frame]
        translation, rotation = _moved_into(translation, rotation, t, q)
    return pl.DataFrame([
        pl.Series("frame_index", boxes.frame_index, dtype=pl.UInt32),
        pl.Series("frame_token", boxes.frame_token, dtype=pl.String),
        pl.Series("annotation_token", boxes.annotation_token, dtype=pl.String),
        pl.Series("instance_token", boxes.instance_token, dtype=pl.String),
        pl.Series("category_name", boxes.category_name, dtype=pl.String),
        columns.to_series("translation", translation),
        columns.to_series("size", boxes.size_wlh_m),
        columns.to_series("rotation", rotation),
        pl.Series("interpolated", boxes.interpolated, dtype=pl.Boolean),
    ])


def _moved_into(translation_m: np.ndarray, rotation_wxyz: np.ndarray, t: np.ndarray, q: np.ndarray):
    """The devkit's `box.translate(-t); box.rotate(Quaternion(q).inverse)` for (M,) boxes and (M,) poses."""
    q_inverse = invert_quaternions(q)
    centre = np.einsum("mij,mj->mi", rotation_matrices(q_inverse), translation_m - t)
    return centre, multiply_quaternions(q_inverse, rotation_wxyz)
