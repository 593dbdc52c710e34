"""The ground truth of an evaluation, from the converted datasets: the devkit's `load_gt` (and the inputs of
`add_center_dist` / `filter_eval_boxes`) as a handful of polars scans.

- samples: the rows of `tables/sample` (in their JSON order: `NuScenes.sample`, the order the devkit walks)
  whose scene is in the split, with the ego position of their reference-lidar keyframe (`frames`);
- boxes: the annotations (`annotations`) of those samples whose category maps to a detection class, in the
  devkit's order: by sample, then as the sample's `anns` list them (the order of `sample_annotation.json`,
  read from `tables/sample_annotation`; it decides which of two equally distant boxes a prediction takes);
  velocity = the stored `velocity` (the devkit's `box_velocity`) in x, y; attribute = the annotation's only
  attribute, '' for none (more than one is an error, as in the devkit); num_pts = lidar + radar points;
- racks: the bicycle racks annotated in those samples (the devkit's bike-rack filter).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl

from nuparquet.columns import to_numpy
from nuparquet.errors import InputError, UsageError
from nuparquet.evaluation.boxes import Boxes
from nuparquet.evaluation.classes import BIKE_RACK_CATEGORY, CATEGORY_TO_DETECTION
from nuparquet.evaluation.splits import split_scene_names
from nuparquet.geometry.cuboids import Cuboids

ANNOTATION_COLUMNS = ("token", "sample_token", "category_name", "attribute_names", "translation", "size", "rotation",
                      "velocity", "num_lidar_pts", "num_radar_pts")


@dataclass(frozen=True)
class Samples:
    """The S evaluated samples, in the devkit's order. token, scene_token, scene_name: (S,) str;
    timestamp_us: (S,) int64; ego_xyz_m: (S, 3) global position of the reference-lidar keyframe's ego pose."""

    token: np.ndarray
    scene_token: np.ndarray
    scene_name: np.ndarray
    timestamp_us: np.ndarray
    ego_xyz_m: np.ndarray

    def __len__(self) -> int:
        return len(self.token)


@dataclass(frozen=True)
class GroundTruth:
    """split: its name; split_scenes: how many scenes the split lists; scenes: the dataset's scenes in the split
    (a `scenes` DataFrame: token, name, log_location, description and any column asked for);
    samples; boxes (class_index into `class_names`); annotations: one row per box, same order (token,
    sample_token, scene_name, timestamp and the annotation columns asked for); racks."""

    split: str
    split_scenes: int
    class_names: tuple[str, ...]
    scenes: pl.DataFrame
    samples: Samples
    boxes: Boxes
    annotations: pl.DataFrame
    racks: Boxes


def load_ground_truth(dataset, split: str, class_names: Sequence[str], *, annotation_columns: Sequence[str] = (),
                      scene_columns: Sequence[str] = (), category_map: dict[str, str] = CATEGORY_TO_DETECTION,
                      one_attribute: bool = True, reference_channel: str | None = None) -> GroundTruth:
    """The ground truth of `split` in `dataset` (a `nuparquet.dataset.Dataset`).

    annotation_columns, scene_columns: extra columns of `annotations` / `scenes` to carry (for slices).
    category_map: category name -> evaluated class (detection's, or `CATEGORY_TO_TRACKING`); one_attribute: refuse
    an evaluated annotation with several attributes (the detection devkit does; the tracking devkit reads none);
    reference_channel: the keyframe whose ego pose the ranges are measured from (None: the dataset's reference
    lidar). A predefined split is the one of the dataset's family (`Dataset.source_format`: nuScenes' or
    TruckScenes' lists).
    Raises UsageError when the split names no scene of the dataset; InputError for data the devkit refuses
    (a sample without reference-lidar keyframe, an evaluated annotation with several attributes).
    """
    for name in ("annotations", "scenes", "frames", "tables/sample", "tables/sample_annotation"):
        if name not in dataset.datasets:
            raise InputError(f"{dataset.root} has no {name} dataset, which the evaluation reads")
    if dataset.row_count("annotations") == 0:  # the devkit: "you do not have the annotations" (a test set)
        raise InputError(f"{dataset.root} has no annotations: there is no ground truth to evaluate against "
                         f"(a test version such as {dataset.version}?)")
    names = split_scene_names(split, dataroot=dataset.dataroot, version=dataset.version,
                              family=dataset.source_format)
    wanted_scene_columns = list(dict.fromkeys(["token", "name", "log_location", "description", *scene_columns]))
    scenes = (dataset.scan("scenes").filter(pl.col("name").is_in(names)).select(wanted_scene_columns)
              .sort("name").collect())
    if scenes.height == 0:
        present = dataset.scan("scenes").select("name").sort("name").collect()["name"].to_list()
        raise UsageError(f"split {split!r} holds none of the dataset's {len(present)} scene(s) "
                         f"({', '.join(present[:8])}{', ...' if len(present) > 8 else ''}); pick the split they "
                         "belong to, or list them in <dataroot>/<version>/splits.json as a custom split")
    scene_names = scenes["name"].to_list()
    reference = reference_channel or dataset.channels.get("reference_lidar")
    if reference_channel is not None and reference_channel not in (dataset.channels.get("lidars") or ()):
        raise InputError(f"{dataset.root} has no {reference_channel}: the devkit measures the class ranges from the "
                         f"ego pose of each sample's {reference_channel} keyframe")
    if reference is None:
        raise InputError(f"{dataset.root} has no lidar: the class ranges are measured from the ego pose of each "
                         "sample's reference-lidar keyframe (LIDAR_TOP in nuScenes)")

    samples_lf = (
        dataset.scan("tables/sample").select("token", "scene_token", pl.col("timestamp").cast(pl.Int64))
        .join(scenes.lazy().select(pl.col("token").alias("scene_token"), pl.col("name").alias("scene_name")),
              on="scene_token", how="inner", maintain_order="left")
    )
    ego_lf = (
        dataset.scan("frames")
        .filter(pl.col("scene_name").is_in(scene_names) & pl.col("is_key_frame")
                & (pl.col("channel").cast(pl.String) == reference))
        .select("sample_token", "ego_translation")
        .unique("sample_token", keep="first", maintain_order=True)
    )
    detection = pl.col("category_name").cast(pl.String).replace_strict(category_map, default=None)
    extra = [c for c in annotation_columns if c not in ANNOTATION_COLUMNS]
    annotations_lf = (
        dataset.scan("annotations").filter(pl.col("scene_name").is_in(scene_names))
        .select(*ANNOTATION_COLUMNS, *[c for c in ("scene_name", "timestamp") if c not in extra], *extra)
        .with_columns(detection_name=detection, category_name=pl.col("category_name").cast(pl.String))
        .filter(pl.col("detection_name").is_not_null() | (pl.col("category_name") == BIKE_RACK_CATEGORY))
    )
    json_order_lf = dataset.scan("tables/sample_annotation").select("token").with_row_index("_json_row")
    samples_df, ego_df, annotations_df = pl.collect_all([samples_lf, ego_lf, annotations_lf])
    annotations_df = (annotations_df.join(json_order_lf.collect(), on="token", how="left")
                      .join(samples_df.select(pl.col("token").alias("sample_token")).with_row_index("_sample_index"),
                            on="sample_token", how="inner")
                      .sort("_sample_index", "_json_row"))

    samples_df = samples_df.join(ego_df, left_on="token", right_on="sample_token", how="left", maintain_order="left")
    no_ego = samples_df.filter(pl.col("ego_translation").is_null())
    if no_ego.height:
        raise InputError(f"sample {no_ego['token'][0]} (scene {no_ego['scene_name'][0]}) has no {reference} keyframe: "
                         f"the devkit measures the class ranges from its ego pose"
                         + (f" ({no_ego.height} such samples)" if no_ego.height > 1 else ""))
    samples = Samples(token=samples_df["token"].to_numpy().astype(object),
                      scene_token=samples_df["scene_token"].to_numpy().astype(object),
                      scene_name=samples_df["scene_name"].to_numpy().astype(object),
                      timestamp_us=samples_df["timestamp"].to_numpy(),
                      ego_xyz_m=to_numpy(samples_df["ego_translation"], (3,), writable=True))

    is_rack = (annotations_df["category_name"] == BIKE_RACK_CATEGORY).to_numpy()
    racks = _boxes(annotations_df.filter(pl.Series(is_rack)), class_index=None)
    evaluated = annotations_df.filter(~pl.Series(is_rack))
    several = evaluated.filter(pl.col("attribute_names").list.len() > 1) if one_attribute else evaluated.clear()
    if several.height:
        raise InputError(f"annotation {several['token'][0]} has {several['attribute_names'][0].len()} attributes; "
                         "the devkit evaluates at most one per box" +
                         (f" ({several.height} such annotations)" if several.height > 1 else ""))
    class_of = {name: i for i, name in enumerate(class_names)}
    class_index = evaluated["detection_name"].replace_strict(class_of, return_dtype=pl.Int64).to_numpy()
    boxes = _boxes(evaluated, class_index=class_index)
    base = ("token", "sample_token", "scene_name", "timestamp", "detection_name")
    table = evaluated.select(*base, *[c for c in dict.fromkeys(annotation_columns) if c not in base])
    return GroundTruth(split=split, split_scenes=len(names), class_names=tuple(class_names), scenes=scenes,
                       samples=samples, boxes=boxes, annotations=table, racks=racks)


def _boxes(df: pl.DataFrame, class_index: np.ndarray | None) -> Boxes:
    n = df.height
    # the first attribute (one_attribute=False lets several through: the tracking evaluation reads none)
    attribute = df["attribute_names"].list.first().fill_null("").to_numpy().astype(object) if n else np.zeros(0, object)
    return Boxes(
        cuboids=Cuboids(to_numpy(df["translation"], (3,), writable=True), to_numpy(df["size"], (3,), writable=True),
                        to_numpy(df["rotation"], (4,), writable=True)),
        sample_index=df["_sample_index"].to_numpy().astype(np.int64),
        class_index=class_index if class_index is not None else np.full(n, -1, np.int64),
        velocity_mps=to_numpy(df["velocity"], (3,), writable=True)[:, :2].copy(),
        attribute=attribute,
        score=np.full(n, -1.0),
        num_pts=(df["num_lidar_pts"] + df["num_radar_pts"]).to_numpy().astype(np.int64),
    )
