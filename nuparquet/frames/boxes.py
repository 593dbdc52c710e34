"""Boxes at a frame's time: the global-frame boxes each frame shows, as devkit `NuScenes.get_boxes` returns them.

A dataset-level query (camera overlays, lidar and map views, training indexes all need it):

```python
frames = ds.scan("frames").filter(pl.col("scene_name") == "scene-0061")
boxes = boxes_for_frames(frames, ds.scan("annotations"), ds.scan("tables/sample"))   # one row per (frame, box)
```

One polars join of row numbers pairs every frame with the annotations of its sample (and, for sweeps, each
annotation with the same instance's annotation one sample earlier); the values are then gathered once with
numpy and the interpolation runs once over all sweep pairs (`geometry.interp_two_points`,
`quaternions.quaternion_slerp`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from nuparquet import columns, geometry
from nuparquet.geometry import quaternions
from nuparquet.geometry.cuboids import CuboidRows, Cuboids

FRAME_COLUMNS = ("token", "sample_token", "timestamp", "is_key_frame")
ANNOTATION_COLUMNS = ("token", "sample_token", "instance_token", "category_name", "translation", "size", "rotation")
SAMPLE_COLUMNS = ("token", "timestamp", "prev")


def lazy_with(frame: pl.DataFrame | pl.LazyFrame, needed: tuple[str, ...], what: str) -> pl.LazyFrame:
    """`frame` as a LazyFrame, after checking it has the `needed` columns (ValueError naming the missing ones)."""
    lazy = frame.lazy()
    missing = [name for name in needed if name not in lazy.collect_schema().names()]
    if missing:
        raise ValueError(f"{what} lacks column(s) {', '.join(missing)}")
    return lazy


@dataclass(frozen=True)
class FramedCuboids(CuboidRows):
    """Cuboids placed on frames, ground truth or predictions: the global-frame `cuboids` and, per box, where it is
    shown and where it came from (what projection, overlays and the bird's-eye view need).

    Attributes:
        cuboids: (M,) the boxes, at "global".
        frame_index: (M,) int64 row of the `frames` passed in.
        source_index: (M,) int64 row of the box among the boxes it came from (the annotations, or the predictions):
            the boxes of one source row share their size and, unless interpolated, their orientation.
        interpolated: (M,) bool, interpolated between two samples (its orientation is its own).
    """

    frame_index: np.ndarray
    source_index: np.ndarray
    interpolated: np.ndarray


@dataclass(frozen=True)
class FrameBoxes(FramedCuboids):
    """M (frame, annotation) boxes, ordered by frame then annotation: `FramedCuboids` whose sources are the
    `annotations` rows of the frames' samples (and the sweeps' previous samples), in the order given.

    Attributes:
        frame_token, annotation_token, instance_token, category_name: (M,) str. For an interpolated sweep box
            the annotation is the current sample's (as the devkit's `Box.token`).
    """

    frame_token: np.ndarray
    annotation_token: np.ndarray
    instance_token: np.ndarray
    category_name: np.ndarray

    @property
    def annotation_index(self) -> np.ndarray:
        """(M,) int64 row of each box's annotation (its `source_index`)."""
        return self.source_index

    def to_polars(self) -> pl.DataFrame:
        """The columns of `boxes_for_frames`."""
        return pl.DataFrame(box_series(self, pl.UInt32))


def box_series(boxes, frame_index_dtype) -> list[pl.Series]:
    """The columns of `boxes_for_frames` from boxes with its fields (`FrameBoxes`, `ProjectedBoxes`): frame_index
    (as `frame_index_dtype`), the tokens and category, translation, size, rotation, interpolated."""
    return [
        pl.Series("frame_index", boxes.frame_index, dtype=frame_index_dtype),
        pl.Series("frame_token", boxes.frame_token, dtype=pl.String),
        pl.Series("annotation_token", boxes.annotation_token, dtype=pl.String),
        pl.Series("instance_token", boxes.instance_token, dtype=pl.String),
        pl.Series("category_name", boxes.category_name, dtype=pl.String),
        columns.to_series("translation", boxes.translation_m),
        columns.to_series("size", boxes.size_wlh_m),
        columns.to_series("rotation", boxes.rotation_wxyz),
        pl.Series("interpolated", boxes.interpolated, dtype=pl.Boolean),
    ]


def boxes_for_frames(
    frames: pl.DataFrame | pl.LazyFrame,
    annotations: pl.DataFrame | pl.LazyFrame,
    samples: pl.DataFrame | pl.LazyFrame,
) -> pl.DataFrame:
    """The global-frame boxes of each frame as a DataFrame (see `frame_boxes`): one row per (frame, box),
    ordered by frame then annotation, with frame_index (u32, row of `frames`), frame_token, annotation_token,
    instance_token, category_name, translation (global, m), size ([w, l, h], m), rotation (global,
    [w, x, y, z]), interpolated (bool)."""
    return frame_boxes(frames, annotations, samples).to_polars()


def frame_boxes(
    frames: pl.DataFrame | pl.LazyFrame,
    annotations: pl.DataFrame | pl.LazyFrame,
    samples: pl.DataFrame | pl.LazyFrame,
) -> FrameBoxes:
    """The global-frame boxes of each frame, as devkit `NuScenes.get_boxes(frame_token)` returns them.

    A keyframe, or a frame whose sample has no previous sample, gets its sample's annotations unchanged. Any
    other frame (a sweep) gets, for every annotation of its sample, the box interpolated between the same
    instance's annotation in the previous sample (at time t0) and this one (t1), at t = max(t0, min(t1,
    frame timestamp)): centre linearly (as `np.interp`), rotation by pyquaternion's slerp with amount
    (t - t0) / (t1 - t0). Annotations whose instance is not in the previous sample are used unchanged;
    instances only in the previous sample are dropped. The box keeps the current annotation's token, size
    and category, as the devkit's does.

    Args:
        frames: rows of `frames` (any modality): token, sample_token, timestamp, is_key_frame.
        annotations: rows of `annotations` covering the frames' samples and, for sweeps, their previous
            samples: token, sample_token, instance_token, category_name, translation, size, rotation.
        samples: rows of `tables/sample` covering the frames' samples and their previous samples: token,
            timestamp, prev.

    Raises:
        ValueError: a frame's sample, or the previous sample of a sweep's sample, is not in `samples`.
    """
    frames_lazy = lazy_with(frames, FRAME_COLUMNS, "frames")
    annotations_lazy = lazy_with(annotations, ANNOTATION_COLUMNS, "annotations")
    samples_lazy = lazy_with(samples, SAMPLE_COLUMNS, "samples")

    frame_samples = _frame_samples(frames_lazy, samples_lazy)
    _check_samples_known(frame_samples)
    boxes = _annotations_of(frame_samples, annotations_lazy)
    frame_index, annotation_index = _pairs(frame_samples, boxes)

    # Only row numbers were joined; every value is gathered once from its own table (F frames, A annotations).
    translation_a = columns.to_numpy(boxes["translation"], (3,))
    rotation_a = columns.to_numpy(boxes["rotation"], (4,))
    translation_m = translation_a[annotation_index]
    rotation_wxyz = rotation_a[annotation_index]
    interpolate = np.zeros(len(frame_index), dtype=bool)
    between = frame_samples["between_samples"].to_numpy()
    if between.any():
        rows, previous = _previous_annotations(frame_samples, boxes, frame_index, annotation_index, between)
        interpolate[rows] = True
        frames_of_rows = frame_index[rows]
        t0, t1, t_frame = (frame_samples[name].gather(frames_of_rows).to_numpy().astype(np.int64)
                           for name in ("prev_sample_timestamp", "sample_timestamp", "frame_timestamp"))
        t = np.maximum(t0, np.minimum(t1, t_frame))
        translation_m[rows] = geometry.interp_two_points(t, t0, t1, translation_a[previous], translation_m[rows])
        rotation_wxyz[rows] = quaternions.quaternion_slerp(rotation_a[previous], rotation_wxyz[rows],
                                                           geometry.slerp_amount(t, t0, t1))

    return FrameBoxes(
        cuboids=Cuboids(translation_m, columns.to_numpy(boxes["size"], (3,))[annotation_index], rotation_wxyz),
        frame_index=frame_index,
        source_index=annotation_index,
        interpolated=interpolate,
        frame_token=frame_samples["frame_token"].to_numpy()[frame_index],
        annotation_token=boxes["token"].to_numpy()[annotation_index],
        instance_token=boxes["instance_token"].to_numpy()[annotation_index],
        category_name=boxes["category_name"].cast(pl.String).to_numpy()[annotation_index],
    )


def _frame_samples(frames: pl.LazyFrame, samples: pl.LazyFrame) -> pl.DataFrame:
    """Each frame (F rows, in order) with its sample's timestamp and previous sample (token, timestamp)."""
    return (
        frames.select(
            pl.col("token").alias("frame_token"),
            "sample_token",
            pl.col("timestamp").alias("frame_timestamp"),
            "is_key_frame",
        )
        .join(
            samples.select(
                pl.col("token").alias("sample_token"),
                pl.col("timestamp").alias("sample_timestamp"),
                pl.col("prev").alias("prev_sample_token"),
            ),
            on="sample_token",
            how="left",
            maintain_order="left",
        )
        .join(
            samples.select(
                pl.col("token").alias("prev_sample_token"),
                pl.col("timestamp").alias("prev_sample_timestamp"),
            ),
            on="prev_sample_token",
            how="left",
            maintain_order="left",
        )
        # get_boxes interpolates exactly when the frame is not a keyframe and its sample has a prev.
        .with_columns((~pl.col("is_key_frame") & (pl.col("prev_sample_token") != "")).alias("between_samples"))
        .collect()
    )


def _annotations_of(frame_samples: pl.DataFrame, annotations: pl.LazyFrame) -> pl.DataFrame:
    """The annotations of the frames' samples and of the sweeps' previous samples, in the order given (a
    filter, so a lazy scan of every annotation reads only those)."""
    needed = pl.concat([
        frame_samples["sample_token"],
        frame_samples.filter(pl.col("between_samples"))["prev_sample_token"],
    ]).unique()
    return annotations.filter(pl.col("sample_token").is_in(needed.implode())).select(ANNOTATION_COLUMNS).collect()


def _pairs(frame_samples: pl.DataFrame, boxes: pl.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """(M,) frame rows and (M,) annotation rows of every (frame, box of its sample) pair, ordered by frame
    then annotation. Samples become small integer codes (one join per table, F and A rows); the pairs are then
    laid out with numpy: each frame takes its sample's run of annotations (annotations grouped by sample with
    a stable sort, so each run keeps the annotations' order)."""
    codes = frame_samples.select("sample_token").unique(maintain_order=True).with_row_index("code")
    frame_code = (frame_samples.select("sample_token").join(codes, on="sample_token", how="left",
                                                            maintain_order="left")["code"].to_numpy().astype(np.int64))
    unknown = codes.height  # annotations of a previous sample only: no frame takes them
    box_code = (boxes.select("sample_token").join(codes, on="sample_token", how="left", maintain_order="left")["code"]
                .fill_null(unknown).to_numpy().astype(np.int64))
    by_sample = np.argsort(box_code, kind="stable")
    counts = np.bincount(box_code, minlength=unknown + 1)[:unknown]
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    per_frame = counts[frame_code]
    frame_index = np.repeat(np.arange(len(frame_code), dtype=np.int64), per_frame)
    first_pair = np.cumsum(per_frame) - per_frame
    within = np.arange(len(frame_index), dtype=np.int64) - np.repeat(first_pair, per_frame)
    annotation_index = by_sample[np.repeat(starts[frame_code], per_frame) + within].astype(np.int64)
    return frame_index, annotation_index


def _previous_annotations(frame_samples: pl.DataFrame, boxes: pl.DataFrame, frame_index: np.ndarray,
                          annotation_index: np.ndarray, between: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For the pairs of sweep frames: the pair rows whose instance has an annotation in the previous sample,
    and the row of that annotation in `boxes`."""
    rows = np.flatnonzero(between[frame_index])
    sweep_pairs = pl.DataFrame({
        "row": rows,
        "prev_sample_token": frame_samples["prev_sample_token"].gather(frame_index[rows]),
        "instance_token": boxes["instance_token"].gather(annotation_index[rows]),
    })
    previous = (
        boxes.select(pl.col("sample_token").alias("prev_sample_token"), "instance_token")
        .with_row_index("previous")
        # The devkit maps instance -> previous annotation with a dict, so a (malformed) duplicate instance
        # in one sample yields one box, the last one, rather than one box per duplicate.
        .unique(["prev_sample_token", "instance_token"], keep="last", maintain_order=True)
    )
    matched = sweep_pairs.join(previous, on=["prev_sample_token", "instance_token"], how="inner").sort("row")
    return matched["row"].to_numpy().astype(np.int64), matched["previous"].to_numpy().astype(np.int64)


def _check_samples_known(frame_samples: pl.DataFrame) -> None:
    """Raise if a frame's sample (or a sweep's previous sample) was not passed: its boxes would silently go."""
    unknown = (
        frame_samples.filter(
            pl.col("sample_timestamp").is_null()
            | (pl.col("between_samples") & pl.col("prev_sample_timestamp").is_null())
        )
        .select("frame_token", "sample_token", "prev_sample_token")
        .head(1)
    )
    if unknown.height:
        row = unknown.row(0, named=True)
        missing = row["sample_token"] if row["prev_sample_token"] is None else row["prev_sample_token"]
        raise ValueError(
            f"samples lacks sample {missing!r} needed for frame {row['frame_token']!r}; pass the sample table "
            "rows of the frames' samples and of their previous samples"
        )
