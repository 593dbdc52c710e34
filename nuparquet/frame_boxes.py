"""Boxes at a frame's time: the global-frame boxes each frame shows, as devkit `NuScenes.get_boxes` returns them.

A dataset-level query (camera overlays, lidar and map views, training indexes all need it):

```python
frames = ds.scan("frames").filter(pl.col("scene_name") == "scene-0061")
boxes = boxes_for_frames(frames, ds.scan("annotations"), ds.scan("tables/sample"))   # one row per (frame, box)
```

One polars join pairs every frame with the annotations of its sample and, for sweeps, each annotation with
the same instance's annotation one sample earlier; the interpolation then runs once over all pairs in numpy
(`geometry.interp_two_points`, `quaternions.quaternion_slerp`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import polars as pl

from nuparquet import columns, geometry, quaternions

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
class FrameBoxes:
    """M (frame, box) pairs as aligned arrays, ordered by frame then annotation.

    Attributes:
        frame_index: (M,) int64 row of the `frames` passed in.
        frame_token, annotation_token, instance_token, category_name: (M,) str. For an interpolated sweep box
            the annotation is the current sample's (as the devkit's `Box.token`).
        translation_m: (M, 3) box centre in the global frame, metres.
        size_wlh_m: (M, 3) [width, length, height], metres.
        rotation_wxyz: (M, 4) orientation in the global frame, quaternion [w, x, y, z].
        interpolated: (M,) bool, interpolated between two samples.
    """

    frame_index: np.ndarray
    frame_token: np.ndarray
    annotation_token: np.ndarray
    instance_token: np.ndarray
    category_name: np.ndarray
    translation_m: np.ndarray
    size_wlh_m: np.ndarray
    rotation_wxyz: np.ndarray
    interpolated: np.ndarray

    def __len__(self) -> int:
        return len(self.frame_index)

    def take(self, rows) -> FrameBoxes:
        return FrameBoxes(**{f.name: getattr(self, f.name)[rows] for f in fields(self)})

    def to_polars(self) -> pl.DataFrame:
        """The columns of `boxes_for_frames`."""
        return pl.DataFrame([
            pl.Series("frame_index", self.frame_index, dtype=pl.UInt32),
            pl.Series("frame_token", self.frame_token, dtype=pl.String),
            pl.Series("annotation_token", self.annotation_token, dtype=pl.String),
            pl.Series("instance_token", self.instance_token, dtype=pl.String),
            pl.Series("category_name", self.category_name, dtype=pl.String),
            columns.to_series("translation", self.translation_m),
            columns.to_series("size", self.size_wlh_m),
            columns.to_series("rotation", self.rotation_wxyz),
            pl.Series("interpolated", self.interpolated, dtype=pl.Boolean),
        ])


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
    joined = _join_annotations(frame_samples.lazy(), annotations_lazy)

    interpolate = joined["interpolated"].to_numpy()
    translation_m = columns.to_numpy(joined["translation"], (3,), writable=True)
    rotation_wxyz = columns.to_numpy(joined["rotation"], (4,), writable=True)
    if interpolate.any():
        rows = np.flatnonzero(interpolate)
        part = joined.select(
            "prev_sample_timestamp", "sample_timestamp", "frame_timestamp", "prev_translation", "prev_rotation"
        )[rows]
        t0 = part["prev_sample_timestamp"].to_numpy().astype(np.int64)
        t1 = part["sample_timestamp"].to_numpy().astype(np.int64)
        t = np.maximum(t0, np.minimum(t1, part["frame_timestamp"].to_numpy().astype(np.int64)))
        translation_m[rows] = geometry.interp_two_points(
            t, t0, t1, columns.to_numpy(part["prev_translation"], (3,)), translation_m[rows]
        )
        rotation_wxyz[rows] = quaternions.quaternion_slerp(
            columns.to_numpy(part["prev_rotation"], (4,)), rotation_wxyz[rows], geometry.slerp_amount(t, t0, t1)
        )

    return FrameBoxes(
        frame_index=joined["frame_index"].to_numpy().astype(np.int64),
        frame_token=joined["frame_token"].to_numpy(),
        annotation_token=joined["annotation_token"].to_numpy(),
        instance_token=joined["instance_token"].to_numpy(),
        category_name=joined["category_name"].to_numpy(),
        translation_m=translation_m,
        size_wlh_m=columns.to_numpy(joined["size"], (3,)),
        rotation_wxyz=rotation_wxyz,
        interpolated=interpolate,
    )


def _frame_samples(frames: pl.LazyFrame, samples: pl.LazyFrame) -> pl.DataFrame:
    """Each frame with its sample's timestamp and previous sample (token, timestamp)."""
    return (
        frames.with_row_index("frame_index")
        .select(
            "frame_index",
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
        )
        .join(
            samples.select(
                pl.col("token").alias("prev_sample_token"),
                pl.col("timestamp").alias("prev_sample_timestamp"),
            ),
            on="prev_sample_token",
            how="left",
        )
        # get_boxes interpolates exactly when the frame is not a keyframe and its sample has a prev.
        .with_columns((~pl.col("is_key_frame") & (pl.col("prev_sample_token") != "")).alias("between_samples"))
        .collect()
    )


def _join_annotations(frame_samples: pl.LazyFrame, annotations: pl.LazyFrame) -> pl.DataFrame:
    """Each frame with its sample's boxes, and each box with the same instance's box one sample earlier."""
    return (
        frame_samples.join(
            annotations.with_row_index("annotation_index").select(
                "annotation_index",
                "sample_token",
                pl.col("token").alias("annotation_token"),
                "instance_token",
                pl.col("category_name").cast(pl.String),
                "translation",
                "size",
                "rotation",
            ),
            on="sample_token",
            how="inner",
        )
        .join(
            annotations.select(
                pl.col("sample_token").alias("prev_sample_token"),
                "instance_token",
                pl.col("translation").alias("prev_translation"),
                pl.col("rotation").alias("prev_rotation"),
            )
            # The devkit maps instance -> previous annotation with a dict, so a (malformed) duplicate instance
            # in one sample yields one box, the last one, rather than one box per duplicate.
            .unique(["prev_sample_token", "instance_token"], keep="last", maintain_order=True),
            on=["prev_sample_token", "instance_token"],
            how="left",
        )
        .with_columns((pl.col("between_samples") & pl.col("prev_translation").is_not_null()).alias("interpolated"))
        # Joins do not promise an order; callers line boxes up with frames, so fix one.
        .sort("frame_index", "annotation_index")
        .collect()
    )


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
