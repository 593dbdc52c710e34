"""One annotation, and one instance, as devkit `render_annotation` / `render_instance` show them.

`render_annotation`: the sample's reference lidar keyframe seen from above in its sensor frame (points coloured by
their height, `render_height`; `view` applied), framed on the box with `margin` metres around it, beside the first of
the sample's keyframe cameras (in the devkit's `sample['data']` order: the sample_data file's) whose boxes at
`box_vis_level` include the annotation, with that box drawn. `extra_info` adds the devkit's text: category, lidar
and radar points, distance to the ego, size.

`render_instance`: the annotation of the instance nearest to the ego (the devkit's choice: 3-D distance from the
sample's reference lidar ego pose, the first of equals in file order), or with `annotation="middle"` the one in the
middle of its track in time. Both return (H, W, 3) uint8 RGB.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet import columns, geometry
from nuparquet.dataset import as_dataset
from nuparquet.errors import UsageError
from nuparquet.rendering import legend
from nuparquet.rendering.pictures.clouds import frame_frame, lidar_cloud
from nuparquet.rendering.overlay import category_colors
from nuparquet.rendering.point_colors import scalar_rgb
from nuparquet.rendering.pictures.sample_data import camera_image, reference_keyframe, visibility_name
from nuparquet.rendering.pictures.topview import PlaneView

INSTANCE_CHOICES = ("closest", "middle")


def annotation_row(dataset, token: str) -> dict:
    rows = dataset.scan("annotations").filter(pl.col("token") == token).collect()
    if rows.is_empty():
        raise UsageError(f"no annotation (sample_annotation) {token!r} in {dataset.root}")
    return rows.with_columns(pl.col("category_name").cast(pl.String)).row(0, named=True)


def cameras_in_sample_order(dataset, sample_token: str) -> list[str]:
    """The sample's keyframe camera tokens in the devkit's `sample['data']` order: the sample_data file's order."""
    keyframes = (dataset.scan("tables/sample_data").with_row_index("_file")
                 .filter((pl.col("sample_token") == sample_token) & pl.col("is_key_frame")).select("token", "_file")
                 .collect())
    cameras = (dataset.scan("frames").filter((pl.col("sample_token") == sample_token) & pl.col("is_key_frame")
                                             & (pl.col("modality").cast(pl.String) == "camera"))
               .select("token", pl.col("channel").cast(pl.String)).collect())
    ordered = keyframes.join(cameras, on="token", how="inner").sort("_file")
    return ordered.unique("channel", keep="first", maintain_order=True)["token"].to_list()


def camera_seeing(dataset, sample_token: str, annotation_token: str, visibility: str) -> str:
    """The first keyframe camera (sample order) whose boxes at `visibility` hold the annotation; UsageError if none
    does (the devkit's "Could not find image where annotation is visible")."""
    tokens = cameras_in_sample_order(dataset, sample_token)
    if tokens:
        boxes = dataset.boxes(tokens, visibility=visibility)
        seen = set(boxes.filter(pl.col("annotation_token") == annotation_token)["frame_token"].to_list())
        for token in tokens:
            if token in seen:
                return token
    raise UsageError(f"annotation {annotation_token} is in no camera image at box_vis_level {visibility!r}; "
                     "try box_vis_level='any'")


def lidar_panel(dataset, ref_rows: pl.DataFrame, annotation_token: str, *, margin: float, view: np.ndarray,
                height_px: int) -> np.ndarray:
    """(height_px, W, 3) BGR: the reference lidar keyframe's points in its frame through `view`, coloured by z, on
    the box's corners (through `view`) +- margin (the devkit's render_height and limits)."""
    ref = ref_rows.row(0, named=True)
    boxes = dataset.boxes(ref_rows, at="sensor").filter(pl.col("annotation_token") == annotation_token)
    corners = geometry.box_corners(columns.to_numpy(boxes["translation"], (3,)), columns.to_numpy(boxes["size"], (3,)),
                                   columns.to_numpy(boxes["rotation"], (4,)))
    viewed = geometry.view_points(corners.reshape(-1, 3), view, normalize=False).reshape(corners.shape)
    plane = PlaneView.around(viewed[..., :2].reshape(-1, 2).min(axis=0), viewed[..., :2].reshape(-1, 2).max(axis=0),
                             margin, height_px)
    image = plane.canvas()
    points = lidar_cloud(dataset, ref).points
    xy = geometry.view_points(np.asarray(points[:, :3], np.float64), view, normalize=False)[:, :2]
    inside = ((xy[:, 0] >= plane.x_min) & (xy[:, 0] <= plane.x_max) & (xy[:, 1] >= plane.y_min)
              & (xy[:, 1] <= plane.y_max))
    colours = scalar_rgb(points[:, 2])  # render_height colours by the sensor-frame z over the whole cloud
    plane.draw_points(image, xy[inside], colours[inside], max(2, height_px // 300))
    plane.draw_boxes(image, viewed, category_colors(boxes["category_name"].to_numpy()), max(2, height_px // 300))
    legend.draw_caption(image, ref["channel"])
    return image


def render_annotation(dataset_or_path, anntoken: str, margin: float = 10, view=None, box_vis_level="any",
                      extra_info: bool = False, *, scale: float = 1.0, labels: str = "none") -> np.ndarray:
    """Annotation `anntoken`: its lidar view beside the camera that sees it (the module docstring); `scale` sizes
    the camera image (the lidar panel takes its height)."""
    dataset = as_dataset(dataset_or_path)
    view = np.eye(4) if view is None else np.asarray(view, np.float64)
    annotation = annotation_row(dataset, anntoken)
    sample_token = annotation["sample_token"]
    camera_token = camera_seeing(dataset, sample_token, anntoken, visibility_name(box_vis_level))
    camera = camera_image(dataset, frame_frame(dataset, camera_token), visibility="any", labels=labels,
                          scale=scale, annotation_tokens=[anntoken])
    legend.draw_caption(camera, str(frame_frame(dataset, camera_token)["channel"][0]))
    ref_rows = reference_keyframe(dataset, sample_token)
    lidar = lidar_panel(dataset, ref_rows, anntoken, margin=margin, view=view, height_px=camera.shape[0])
    picture = np.concatenate([lidar, np.zeros((camera.shape[0], 6, 3), np.uint8), camera], axis=1)
    if extra_info:
        picture = np.concatenate([picture, _info_panel(annotation, ref_rows, picture.shape[1])], axis=0)
    return np.ascontiguousarray(picture[..., ::-1])


def _info_panel(annotation: dict, ref_rows: pl.DataFrame, width: int) -> np.ndarray:
    """The devkit's extra_info text (category, lidar and radar points, distance to the ego, w / l / h) on a band."""
    import cv2

    w, l, h = annotation["size"]
    ego = np.asarray(ref_rows["ego_translation"][0].to_list(), np.float64)
    distance = float(np.linalg.norm(ego - np.asarray(annotation["translation"], np.float64)))
    lines = [f"category: {annotation['category_name']}", f"# lidar points: {annotation['num_lidar_pts']:>4}",
             f"# radar points: {annotation['num_radar_pts']:>4}", f"distance: {distance:>7.3f}m",
             f"width:  {w:>7.3f}m", f"length: {l:>7.3f}m", f"height: {h:>7.3f}m"]
    band = np.full((28 * len(lines) + 12, width, 3), 255, np.uint8)
    for i, line in enumerate(lines):
        cv2.putText(band, line, (10, 30 + 28 * i), cv2.FONT_HERSHEY_PLAIN, 1.6, (0, 0, 0), 1, cv2.LINE_AA)
    return band


def instance_annotation(dataset, instance_token: str, annotation: str = "closest") -> str:
    """The annotation of the instance `render_instance` shows: "closest" (the devkit's: nearest to the ego pose of its
    sample's reference lidar keyframe, 3-D, the first of equals in file order) or "middle" (of its track in time)."""
    if annotation not in INSTANCE_CHOICES:
        raise UsageError(f"annotation must be one of {', '.join(INSTANCE_CHOICES)}, got {annotation!r}")
    rows = (dataset.scan("annotations").filter(pl.col("instance_token") == instance_token)
            .select("token", "sample_token", "timestamp", "translation", "file_index").collect())
    if rows.is_empty():
        raise UsageError(f"no instance {instance_token!r} (or no annotation of it) in {dataset.root}")
    if annotation == "middle":
        return rows.sort("timestamp", "file_index")["token"][rows.height // 2]
    reference = dataset.channels.get("reference_lidar")
    poses = (dataset.scan("frames").filter(pl.col("is_key_frame") & (pl.col("channel").cast(pl.String) == reference)
                                           & pl.col("sample_token").is_in(rows["sample_token"].implode()))
             .select("sample_token", "ego_translation").collect())
    rows = rows.join(poses, on="sample_token", how="left").sort("file_index")
    distance = np.linalg.norm(columns.to_numpy(rows["ego_translation"], (3,))
                              - columns.to_numpy(rows["translation"], (3,)), axis=1)
    return rows["token"][int(np.argmin(np.where(np.isnan(distance), np.inf, distance)))]


def render_instance(dataset_or_path, instance_token: str, margin: float = 10, view=None, box_vis_level="any",
                    extra_info: bool = False, *, annotation: str = "closest", scale: float = 1.0,
                    labels: str = "none") -> np.ndarray:
    """`render_annotation` of the instance's annotation chosen by `annotation` (`instance_annotation`)."""
    dataset = as_dataset(dataset_or_path)
    token = instance_annotation(dataset, instance_token, annotation)
    return render_annotation(dataset, token, margin, view, box_vis_level, extra_info, scale=scale, labels=labels)
