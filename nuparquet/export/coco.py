"""`export_coco`: the 2D annotations of a nuImages conversion as a COCO instances file (what mmdetection reads).

    {"images": [{"id", "token", "file_name", "width", "height"}],          every keyframe, sample_data order
     "annotations": [{"image_id", "category_id", "bbox": [x, y, w, h], "area",
                      "segmentation": {"counts": RLE string, "size": [h, w]}, "iscrowd": 0, "id"}],
     "categories": [{"id", "name"(, "supercategory")}]}

Annotations follow their images; within an image the objects are sorted by token (the devkit's instance order);
objects without a mask are left out; `segmentation` is the compressed RLE string itself (base64-decoded), which
pycocotools decodes to the devkit's mask. `classes="mmdet3d"` is mmdetection3d's `nuimage_converter.py` output
byte for byte (its `NAME_MAPPING` to 10 classes, `area` = box width x height, ids from 0); `classes="all"` keeps
every object category (id = the devkit's class index, `nuparquet.nuimages.segmentation.category_indices`) with the
mask's area as COCO defines it.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Any

import polars as pl

from nuparquet.atomic import atomic_file
from nuparquet.dataset import as_dataset
from nuparquet.errors import UsageError
from nuparquet.export.coco_options import CocoOptions
from nuparquet.nuimages.masks import check_nuimages
from nuparquet.nuimages.segmentation import DRIVEABLE, EGO, category_indices
from nuparquet.options import resolve

# mmdetection3d's nuImages classes and its mapping of nuImages categories onto them (nuimage_converter.py)
MMDET3D_CLASSES = ("car", "truck", "trailer", "bus", "construction_vehicle", "bicycle", "motorcycle", "pedestrian",
                   "traffic_cone", "barrier")
MMDET3D_NAMES = {
    "movable_object.barrier": "barrier", "vehicle.bicycle": "bicycle", "vehicle.bus.bendy": "bus",
    "vehicle.bus.rigid": "bus", "vehicle.car": "car", "vehicle.construction": "construction_vehicle",
    "vehicle.motorcycle": "motorcycle", "human.pedestrian.adult": "pedestrian", "human.pedestrian.child": "pedestrian",
    "human.pedestrian.construction_worker": "pedestrian", "human.pedestrian.police_officer": "pedestrian",
    "movable_object.trafficcone": "traffic_cone", "vehicle.trailer": "trailer", "vehicle.truck": "truck",
}


def coco_instances(dataset_or_path, options: CocoOptions | None = None, **fields: Any) -> dict:
    """The COCO instances dict of a nuImages conversion (see the module docstring)."""
    options = resolve(CocoOptions, options, fields)
    ds = as_dataset(dataset_or_path)
    check_nuimages(ds)
    images = (ds.scan("tables/sample_data").filter(pl.col("is_key_frame"))
              .select(pl.int_range(pl.len()).alias("id"), "token", pl.col("filename").alias("file_name"), "width",
                      "height").collect())
    names = ds.scan("tables/category").select("name").collect()["name"].to_list()
    if options.classes == "mmdet3d":
        categories = [{"id": i, "name": name} for i, name in enumerate(MMDET3D_CLASSES)]
        ids = {source: MMDET3D_CLASSES.index(target) for source, target in MMDET3D_NAMES.items()}
    else:
        indices = category_indices(names)
        ids = {name: indices[name] for name in names if name not in (DRIVEABLE, EGO)}
        categories = [{"id": ids[name], "name": name, "supercategory": name.split(".")[0]}
                      for name in sorted(ids, key=ids.get)]
    objects = (ds.scan("objects").filter(pl.col("mask_counts").is_not_null()
                                         & pl.col("category_name").cast(pl.String).is_in(list(ids)))
               .select("token", "sample_data_token", pl.col("category_name").cast(pl.String), "bbox", "mask_height",
                       "mask_width", "mask_counts", "mask_area")
               .join(images.lazy().select(pl.col("token").alias("sample_data_token"), pl.col("id").alias("image_id")),
                     on="sample_data_token", how="inner")
               .sort("image_id", "token").collect())
    annotations = []
    for row in objects.iter_rows(named=True):
        x0, y0, x1, y1 = row["bbox"]
        annotations.append({
            "image_id": row["image_id"], "category_id": ids[row["category_name"]], "bbox": [x0, y0, x1 - x0, y1 - y0],
            "area": (x1 - x0) * (y1 - y0) if options.classes == "mmdet3d" else row["mask_area"],
            "segmentation": {"counts": base64.b64decode(row["mask_counts"]).decode(),
                             "size": [row["mask_height"], row["mask_width"]]},
            "iscrowd": 0, "id": len(annotations)})
    return {"images": images.to_dicts(), "annotations": annotations, "categories": categories}


def export_coco(dataset, out: Path | str, options: CocoOptions | None = None, **fields: Any) -> Path:
    """Write the COCO instances file of a nuImages conversion to `out` (atomically); returns `out`."""
    options = resolve(CocoOptions, options, fields)
    out = Path(out)
    if out.exists() and not options.overwrite:
        raise UsageError(f"{out} already exists; pass --overwrite to replace it")
    if out.is_dir():
        raise UsageError(f"{out} is a directory; name the JSON file to write")
    instances = coco_instances(dataset, options)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(out) as partial:
        partial.write_text(json.dumps(instances))
    return out
