"""The irregular profile of the generator (`synthesize(..., profile="irregular")`): the same scenes, reshaped
to hold the cases regular data never shows, so that tests against the devkit can see the rules that only
matter there.

What changes, scene by scene (its own seeded generator; the regular draws are untouched):
- Sample timestamps are exact multiples of 0.5 s (`1e-6 * t` differences are then exact: a 1.5 s gap is
  exactly 1.5 s, where devkit `box_velocity`'s strict `>` matters), every frame shifted with its sample.
- Camera sweeps within 20 ms of a 10 Hz clock tick (devkit `render_scene`'s default time step, counted from
  the first sample) are moved onto the tick: ties between a clock step and a frame timestamp.
- In the first scene, CAM_FRONT's first keyframe comes 250 ms after the first sample, after sweeps of the
  first sample: a camera whose first keyframe comes late, with frames before it.
- Tracks of eight annotations or more lose runs of annotations (`GAP_PATTERNS`): gaps of 1 to 3 s, on one side
  or both sides of an annotation (prev/next link across the gap, as in nuScenes; get_boxes does not
  interpolate sweep boxes across it, since the instance is absent from the sample before).
- Terrain is not flat: `ground_z_m` raises the ego poses and the boxes.
- At two keyframes per scene, small single-annotation boxes stand 0.05 to 1.5 m in front of CAM_FRONT
  (`NEAR_BOX_DEPTHS_M`) with many lidar points on them: boxes and points closer than the devkit's 1 m
  `box_in_image` / `min_dist` limits and its 0.1 m `in_front` limit.
- A second version folder `<version>-test` holds the same tables with empty `sample_annotation` and
  `instance` tables and no lidarseg/panoptic index tables, as nuScenes v1.0-test has.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np

from nuparquet.atomic import move_into_place
from nuparquet.synth.plan import Rig
from nuparquet.synth.rigid import rigid_matrix
from nuparquet.synth.taxonomy import CATEGORY_INDEX, KEYFRAME_INTERVAL_US
from nuparquet.synth.timeline import Timeline
from nuparquet.synth.world import SceneWorld

EMPTY_ANNOTATIONS_SUFFIX = "-test"
CLOCK_STEP_US = 100_000  # devkit render_scene(freq=10)
TIE_WINDOW_US = 20_000
LATE_FIRST_FRAME_US = 250_000
LATE_CHANNEL = "CAM_FRONT"
# Positions removed from a track (0 = its first annotation), cycled over the tracks long enough for them.
# Exact gaps with 0.5 s samples: {1, 2} -> 1.5 s after the first annotation (one-sided, at the limit);
# {1, 2, 4, 5} -> 1.5 s on both sides of position 3 (centred, 3.0 s: at the doubled limit); {2, 3, 4} -> 2 s;
# {1, ..., 5} -> 3 s (beyond both limits); {3} -> 1 s; {1, 2, 3} -> 2 s after the first (one-sided, over).
GAP_PATTERNS = ((1, 2), (1, 2, 4, 5), (2, 3, 4), (1, 2, 3, 4, 5), (3,), (1, 2, 3))
MIN_GAPPED_TRACK = 8
# Camera-frame offsets (x right, depth z forward) of the near boxes and their cube edge, metres.
NEAR_BOX_DEPTHS_M = (0.05, 0.5, 0.8, 1.2, 1.5)
NEAR_BOX_X_M = (0.0, -0.25, 0.0, 0.3, -0.4)
NEAR_BOX_EDGE_M = (0.3, 0.3, 0.3, 0.6, 0.5)
NEAR_BOX_LIDAR_PTS = 80


def ground_z_m(xy_m: np.ndarray) -> np.ndarray:
    """(..., 2) global positions -> (...,) ground height: gentle hills (slopes of a few percent), always
    above -1.5 m so that the lidar (1.8 m up) still sees the plane z = 0 the sensor files draw."""
    return 0.5 + 0.8 * np.sin(xy_m[..., 0] / 37.0) + 0.6 * np.cos(xy_m[..., 1] / 53.0)


def scene_rng(seed: int, scene_index: int) -> np.random.Generator:
    return np.random.default_rng([seed, 3, scene_index])


def irregular_timeline(timeline: Timeline, channels, scene_index: int) -> Timeline:
    """Exact 0.5 s samples, clock ties and (first scene) a late first CAM_FRONT frame; see the module doc."""
    old_samples = timeline.sample_timestamp_us
    first_us = int(old_samples[0]) // KEYFRAME_INTERVAL_US * KEYFRAME_INTERVAL_US
    samples = first_us + np.arange(old_samples.size, dtype=np.int64) * KEYFRAME_INTERVAL_US
    stamps = timeline.frame_timestamp_us + (samples - old_samples)[timeline.frame_sample_index]
    channel = timeline.frame_channel
    sample_index = timeline.frame_sample_index.copy()
    for c, ch in enumerate(channels):
        if ch.modality != "camera":
            continue
        rows = np.flatnonzero(channel == c)
        if scene_index == 0 and ch.name == LATE_CHANNEL:
            first_key = rows[timeline.frame_is_key_frame[rows]][0]
            late_us = first_us + LATE_FIRST_FRAME_US
            stamps[first_key] = late_us
            # The sweeps it now comes after belong to the first sample: frames before a channel's first
            # keyframe, which the devkit's render_scene never shows (it starts each camera at that keyframe).
            sample_index[rows[(stamps[rows] <= late_us) & ~timeline.frame_is_key_frame[rows]]] = 0
        _snap_to_clock(stamps, rows, timeline.frame_is_key_frame, first_us)
    return _timeline_of(samples, channel, stamps, timeline.frame_is_key_frame, sample_index)


def _snap_to_clock(stamps: np.ndarray, rows: np.ndarray, is_key: np.ndarray, first_us: int) -> None:
    """Move each sweep of one channel (`rows`, in time order) within TIE_WINDOW_US of a clock tick onto it,
    when it stays strictly between its neighbours."""
    for i, row in enumerate(rows):
        if is_key[row]:
            continue
        tick = first_us + round((stamps[row] - first_us) / CLOCK_STEP_US) * CLOCK_STEP_US
        if abs(stamps[row] - tick) > TIE_WINDOW_US:
            continue
        before = stamps[rows[i - 1]] if i > 0 else -np.inf
        after = stamps[rows[i + 1]] if i + 1 < rows.size else np.inf
        if before < tick < after:
            stamps[row] = tick


def _timeline_of(samples, channel, stamps, is_key, sample_index) -> Timeline:
    """Frames ordered by channel, then time, linked to their neighbours of the same channel."""
    order = np.lexsort((stamps, channel))
    channel, stamps, is_key, sample_index = channel[order], stamps[order], is_key[order], sample_index[order]
    index = np.arange(channel.size)
    same_as_prev = np.r_[False, channel[1:] == channel[:-1]]
    same_as_next = np.r_[channel[:-1] == channel[1:], False]
    return Timeline(sample_timestamp_us=samples, frame_channel=channel, frame_timestamp_us=stamps,
                    frame_is_key_frame=is_key, frame_sample_index=sample_index,
                    frame_prev=np.where(same_as_prev, index - 1, -1), frame_next=np.where(same_as_next, index + 1, -1))


def irregular_world(rng: np.random.Generator, world: SceneWorld, rig: Rig) -> SceneWorld:
    """Gapped tracks, hills, and boxes just in front of CAM_FRONT; see the module doc."""
    world = _with_gaps(world)
    ego = world.ego_translation_m.copy()
    ego[:, 2] += ground_z_m(ego[:, :2])
    boxes = world.annotation_translation_m.copy()
    boxes[:, 2] += ground_z_m(boxes[:, :2])
    world = dataclasses.replace(world, ego_translation_m=ego, annotation_translation_m=np.round(boxes, 3))
    return _with_near_boxes(rng, world, rig)


def _with_gaps(world: SceneWorld) -> SceneWorld:
    keep = np.ones(world.annotation_instance.size, dtype=bool)
    long_tracks = np.flatnonzero(world.instance_n_annotations >= MIN_GAPPED_TRACK)
    for j, instance in enumerate(long_tracks):
        removed = np.asarray(GAP_PATTERNS[j % len(GAP_PATTERNS)])
        keep[world.instance_first_annotation[instance] + removed] = False
    n = np.bincount(world.annotation_instance[keep], minlength=world.instance_category.size)
    fields = {f.name: getattr(world, f.name)[keep] for f in dataclasses.fields(world) if f.name.startswith("annotation_")}
    return dataclasses.replace(world, **fields, instance_n_annotations=n.astype(np.int64),
                               instance_first_annotation=np.r_[0, np.cumsum(n)[:-1]].astype(np.int64))


def _with_near_boxes(rng: np.random.Generator, world: SceneWorld, rig: Rig) -> SceneWorld:
    """Single-annotation cones in front of CAM_FRONT at its keyframes of two samples (1 and the one before last)."""
    names = [c.name for c in rig.channels]
    if "CAM_FRONT" not in names:
        return world
    camera = names.index("CAM_FRONT")
    tl = world.timeline
    k_samples = tl.sample_timestamp_us.size
    samples = sorted({min(1, k_samples - 1), max(k_samples - 2, 0)})
    ego_from_camera = rigid_matrix(rig.ego_from_sensor_translation_m[camera], rig.ego_from_sensor_rotation[camera])
    centers, rotations, sample_of, sizes = [], [], [], []
    for k in samples:
        frame = np.flatnonzero((tl.frame_channel == camera) & tl.frame_is_key_frame & (tl.frame_sample_index == k))[0]
        global_from_camera = rigid_matrix(world.ego_translation_m[frame], world.ego_rotation[frame]) @ ego_from_camera
        for depth, x, edge in zip(NEAR_BOX_DEPTHS_M, NEAR_BOX_X_M, NEAR_BOX_EDGE_M):
            centers.append((global_from_camera @ np.array([x, 0.0, depth, 1.0]))[:3])
            rotations.append(world.ego_rotation[frame])
            sample_of.append(k)
            sizes.append([edge, edge, edge])
    n = len(centers)
    i0, a0 = world.instance_category.size, world.annotation_instance.size
    cat = CATEGORY_INDEX["movable_object.trafficcone"]
    return dataclasses.replace(
        world,
        instance_category=np.r_[world.instance_category, np.full(n, cat)],
        instance_first_annotation=np.r_[world.instance_first_annotation, a0 + np.arange(n)],
        instance_n_annotations=np.r_[world.instance_n_annotations, np.ones(n, dtype=np.int64)],
        annotation_instance=np.r_[world.annotation_instance, i0 + np.arange(n)],
        annotation_sample=np.r_[world.annotation_sample, np.array(sample_of, dtype=np.int64)],
        annotation_translation_m=np.r_[world.annotation_translation_m, np.round(np.array(centers), 3)],
        annotation_size_m=np.r_[world.annotation_size_m, np.array(sizes)],
        annotation_rotation=np.r_[world.annotation_rotation, np.array(rotations)],
        annotation_attribute=np.r_[world.annotation_attribute, np.full(n, -1)],
        annotation_visibility=np.r_[world.annotation_visibility, np.full(n, 4)],
        annotation_num_lidar_pts=np.r_[world.annotation_num_lidar_pts, np.full(n, NEAR_BOX_LIDAR_PTS)],
        annotation_num_radar_pts=np.r_[world.annotation_num_radar_pts, rng.integers(0, 2, n)],
    )


def write_empty_annotation_version(dataroot: Path, version: str) -> str:
    """Copy `<version>`'s tables to `<version>-test` with empty sample_annotation and instance tables; returns
    the new version name. Written in a hidden sibling and renamed, like the main tables."""
    name = version + EMPTY_ANNOTATIONS_SUFFIX
    partial, target = dataroot / f".{name}.partial", dataroot / name
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir()
    for table in sorted((dataroot / version).glob("*.json")):
        if table.stem in ("lidarseg", "panoptic"):  # point labels are annotations too: v1.0-test has none
            continue
        empty = table.stem in ("sample_annotation", "instance")
        (partial / table.name).write_text(json.dumps([]) if empty else table.read_text())
    if target.exists():
        shutil.rmtree(target)
    move_into_place(partial, target)
    return name
