"""Pictures of one thing, each an (H, W, 3) uint8 RGB array, with the devkit's names and arguments (so that
`nuparquet.devkit.NuScenes.render_*` is a thin call), and `save_image` to write one as PNG or JPEG.

```python
from nuparquet.rendering.pictures import single
ds = nuparquet.open("OUT")
image = single.render_sample_data(ds, token, nsweeps=5)          # camera with boxes, or lidar / radar from above
image = single.render_pointcloud_in_image(ds, sample_token, point_color="lidarseg", show_lidarseg_legend=True)
image = single.render_annotation(ds, annotation_token)           # lidar view beside the camera that sees it
image = single.render_instance(ds, instance_token)
image = single.render_sample(ds, sample_token)                   # every sensor in one picture
image = single.render_map_patch(ds, "boston-seaport", (300, 1000, 500, 1200))
image = single.render_map_in_image(ds, sample_token, camera_channel="CAM_FRONT")
single.save_image(image, "picture.png")
```

`render_image(ds, ImageOptions(...))` is what `nuparquet render OUT --sample TOKEN ... --out picture.png` runs.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from nuparquet.atomic import atomic_file
from nuparquet.dataset import as_dataset
from nuparquet.errors import EnvironmentFault, UsageError
from nuparquet.options import resolve
from nuparquet.rendering.pictures.annotation import instance_annotation, render_annotation, render_instance
from nuparquet.rendering.pictures.image_options import ImageOptions, check_image_path
from nuparquet.rendering.pictures.map_in_image import render_map_in_image
from nuparquet.rendering.pictures.map_views import (
    ego_poses_on_map, render_centerlines, render_egoposes_on_map, render_layers, render_map_mask, render_map_patch,
    render_next_roads, render_record,
)
from nuparquet.rendering.pictures.pointcloud_image import render_pointcloud_in_image
from nuparquet.rendering.pictures.sample_data import render_sample_data
from nuparquet.rendering.pictures.sample_grid import render_sample

__all__ = [
    "ImageOptions", "ego_poses_on_map", "instance_annotation", "render_annotation", "render_centerlines",
    "render_egoposes_on_map", "render_image", "render_instance", "render_layers", "render_map_in_image",
    "render_map_mask", "render_map_patch", "render_next_roads", "render_pointcloud_in_image", "render_record",
    "render_sample", "render_sample_data", "save_image",
]


def save_image(image_rgb: np.ndarray, path) -> Path:
    """Write an (H, W, 3) RGB picture as PNG or JPEG (by the suffix), atomically (a hidden partial, then renamed)."""
    path = check_image_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    ok, data = cv2.imencode(path.suffix.lower(), np.ascontiguousarray(np.asarray(image_rgb)[..., ::-1]))
    if not ok:
        raise EnvironmentFault(f"could not encode {path}")
    try:
        with atomic_file(path) as partial:
            partial.write_bytes(data.tobytes())
    except OSError as exc:
        raise EnvironmentFault(f"{path}: {exc.strerror or exc}") from exc
    return path


def render_image(dataset, options: ImageOptions | None = None, **fields) -> np.ndarray:
    """The one picture of `dataset` (a `Dataset` or a path; its `dataroot` is where the images are) that `options`
    (or keyword fields of `ImageOptions`) asks for, at full size unless `scale` says otherwise."""
    options = resolve(ImageOptions, options, fields)
    options.check()
    dataset = as_dataset(dataset)
    labels, lidar_color, scenes = options.labels, options.lidar_color, options.scenes
    sized = {} if options.scale is None else {"scale": options.scale}  # else each picture's own default (full size)
    labelled = dict(point_color=lidar_color, filter_lidarseg_labels=options.class_indices(),
                    lidarseg_preds_bin_path=options.lidarseg_preds)
    if options.map is not None:
        return _map_picture(dataset, options, scenes)
    if options.sample is not None:
        if options.map_in_image:
            return render_map_in_image(dataset, options.sample, options.camera_channel or "CAM_FRONT",
                                       layer_names=list(options.map_layers) or None, **sized)
        if options.pointcloud_in_image:
            return render_pointcloud_in_image(dataset, options.sample, pointsensor_channel=options.pointsensor_channel,
                                              camera_channel=options.camera_channel,
                                              show_lidarseg_legend=options.lidarseg_legend, **sized,
                                              **labelled)
        return render_sample(dataset, options.sample, options.box_vis_level, options.nsweeps, **sized,
                             axes_limit=options.axes_limit, underlay_map=options.underlay_map,
                             **(labelled | {"point_color": "depth" if lidar_color == "intensity" else lidar_color}))
    if options.sample_data is not None and dataset.source_format == "nuimages":  # an image with boxes and masks
        from nuparquet.rendering.pictures.nuimages import render_nuimage

        return render_nuimage(dataset, options.sample_data, with_category=labels != "none",
                              render_scale=options.scale or 1.0)
    if options.sample_data is not None:
        return render_sample_data(dataset, options.sample_data, box_vis_level=options.box_vis_level,
                                  axes_limit=options.axes_limit, nsweeps=options.nsweeps,
                                  underlay_map=options.underlay_map, show_lidarseg_legend=options.lidarseg_legend,
                                  labels=labels,
                                  **sized, truth_beside_preds=True, **labelled)
    common = dict(box_vis_level=options.box_vis_level, extra_info=options.extra_info, labels=labels, **sized)
    if options.annotation is not None:
        return render_annotation(dataset, options.annotation, **common)
    return render_instance(dataset, options.instance, annotation=options.instance_annotation, **common)


def _map_picture(dataset, options: ImageOptions, scenes: tuple[str, ...]) -> np.ndarray:
    location, picture = options.map, options.map_picture()
    layers = list(options.map_layers) or None
    if picture == "map_patch":
        return render_map_patch(dataset, location, options.floats("map_patch", 4), layers)
    if picture == "map_record":
        layer, _, token = options.map_record.partition(":")
        if not token:
            raise UsageError(f"--map-record takes LAYER:TOKEN (e.g. lane:0a1b...), got {options.map_record!r}")
        return render_record(dataset, location, layer, token)
    if picture == "map_mask":
        height, width = (int(v) for v in options.floats("canvas_size", 2))
        return render_map_mask(dataset, location, options.floats("map_mask", 4), options.map_angle, layers,
                               (height, width), n_row=1)
    if picture == "centerlines":
        return render_centerlines(dataset, location)
    if picture == "next_roads":
        x, y = options.floats("next_roads", 2)
        return render_next_roads(dataset, location, x, y)
    tokens = None
    if scenes:
        import polars as pl

        dataset.check_scenes(list(scenes))
        tokens = dataset.scan("scenes").filter(pl.col("name").is_in(list(scenes))).collect()["token"].to_list()
    return render_egoposes_on_map(dataset, location, tokens)
