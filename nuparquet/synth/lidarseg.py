"""nuScenes-lidarseg and Panoptic nuScenes labels of the synthetic lidar keyframes, consistent with the boxes.

For every keyframe of the rig's first lidar (nuScenes: LIDAR_TOP), with `--with-lidar`:

    lidarseg/<version>/<sample_data token>_lidarseg.bin   (P,) uint8: category `index` per point
    panoptic/<version>/<sample_data token>_panoptic.npz    `data` (P,) uint16: index * 1000 + instance id
    <version>/lidarseg.json, <version>/panoptic.json       the index tables (token = the sample_data token)

Semantic label: a point inside an annotation box (devkit `points_in_box`: faces inclusive) gets the box's category
`index` (the first box in annotation order if several); every other point (the ground) gets the index of
`flat.driveable_surface`, else 0. Panoptic label as the devkit's `generate_panoptic_labels` builds it from those:
instance ids numbered per scene from 1 in order of first annotation, points in more than one box of their class
get 0, thing points outside every box 0. The lidarseg category vocabulary (index 0 noise, 24-31 the "stuff"
classes of the real nuScenes-lidarseg category.json) is added to category.json so every index has a name.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from nuparquet.synth.rigid import invert_rigid, quat_to_matrix, transform_points
from nuparquet.synth.tokens import name_token

# The non-object classes of the real nuScenes-lidarseg category.json (index, name, description).
LIDARSEG_EXTRA_CATEGORIES = (
    (0, "noise", "Any lidar return that does not correspond to a physical object, such as dust, vapor, noise, fog, "
                 "raindrops, smoke and reflections."),
    (24, "flat.driveable_surface", "All paved or unpaved surfaces that a car can drive on with no concern of traffic "
                                   "rules."),
    (25, "flat.other", "All other forms of horizontal ground-level structures that do not belong to any of "
                       "driveable_surface, curb, sidewalk and terrain. Includes elevated parts of traffic islands, "
                       "delimiters, rail tracks, stairs with at most 3 steps and larger bodies of water - lakes, rivers."),
    (26, "flat.sidewalk", "Sidewalk, pedestrian walkways, bike paths, etc. Part of the ground designated for "
                          "pedestrians or cyclists. Sidewalks do **not** have to be next to a road."),
    (27, "flat.terrain", "Natural horizontal surfaces such as ground level horizontal vegetation (< 20 cm tall), "
                         "grass, rolling hills, soil, sand and gravel."),
    (28, "static.manmade", "Includes man-made structures but not limited to: buildings, walls, guard rails, fences, "
                           "poles, drainages, hydrants, flags, banners, street signs, electric circuit boxes, traffic "
                           "lights, parking meters and stairs with more than 3 steps."),
    (29, "static.other", "Points in the background that are not distinguishable, or objects that do not match any "
                         "of the above labels."),
    (30, "static.vegetation", "Any vegetation in the frame that is higher than the ground, including bushes, plants, "
                              "potted plants, trees, etc. Only tall grass (> 20cm) is part of this, ground level grass "
                              "is part of `terrain`."),
    (31, "vehicle.ego", "The vehicle on which the cameras, radar and lidar are mounted, that is sometimes visible at "
                        "the bottom of the image."),
)
GROUND_CATEGORY = "flat.driveable_surface"
STUFF_START_INDEX = 24  # devkit panoptic_utils.STUFF_START_CLASS_ID: indices 1..23 are "things"


def with_lidarseg_categories(categories: list[dict]) -> list[dict]:
    """category.json records plus the lidarseg classes whose `index` they lack."""
    have = {c.get("index") for c in categories}
    extra = [{"token": name_token("category", name), "name": name, "description": description, "index": index}
             for index, name, description in LIDARSEG_EXTRA_CATEGORIES if index not in have]
    return categories + extra


def points_in_boxes(points_box: np.ndarray, half_lwh: np.ndarray) -> np.ndarray:
    """(B, N) bool: points (B, N, 3) given in each box's frame inside the box (faces included, as devkit
    `points_in_box`) of half extents (B, 3) along its x (length), y (width), z (height)."""
    return (np.abs(points_box) <= half_lwh[:, None, :]).all(axis=2)


class LabelWriter:
    """Writes the label files scene by scene and the two index tables at the end (`close`)."""

    def __init__(self, dataroot: Path, table_dir: Path, version: str, categories: list[dict]):
        self.dataroot, self.table_dir, self.version = dataroot, table_dir, version
        index_of = {c["name"]: c["index"] for c in categories}
        self.ground_index = index_of.get(GROUND_CATEGORY, 0)
        self.lidarseg: list[dict] = []
        self.panoptic: list[dict] = []
        for folder in ("lidarseg", "panoptic"):
            (dataroot / folder / version).mkdir(parents=True, exist_ok=True)
            for stale in (dataroot / folder / version).glob("*"):  # the devkit counts the files: none left over
                stale.unlink()

    def write_scene(self, sensors, frame_tokens: np.ndarray, instance_tokens: np.ndarray,
                    category_index: np.ndarray) -> None:
        """Label every keyframe of the rig's first lidar. `sensors` is the scene's `SceneSensors` (its
        `lidar_points` and boxes); `frame_tokens` (M,) the sample_data tokens; `instance_tokens` (I,);
        `category_index` (I,) the category `index` of each instance."""
        world, tl = sensors.world, sensors.world.timeline
        lidars = [i for i, c in enumerate(sensors.rig.channels) if c.modality == "lidar"]
        if not lidars:
            return
        instance_id: dict[str, int] = {}  # per scene, from 1, in order of first annotation (devkit)
        frames = np.flatnonzero((tl.frame_channel == lidars[0]) & tl.frame_is_key_frame)
        for frame in frames[np.argsort(tl.frame_sample_index[frames], kind="stable")]:
            annotations = sensors._annotations_of_sample[int(tl.frame_sample_index[frame])]
            for instance in world.annotation_instance[annotations]:
                instance_id.setdefault(str(instance_tokens[instance]), len(instance_id) + 1)
            points = sensors.lidar_points(int(frame)).astype(np.float32)  # as written to the .pcd.bin
            semantic, panoptic = self.frame_labels(sensors, int(frame), points, annotations, instance_tokens,
                                                   category_index, instance_id)
            token = str(frame_tokens[frame])
            self._write(token, semantic, panoptic)

    def frame_labels(self, sensors, frame: int, points: np.ndarray, annotations: np.ndarray, instance_tokens,
                     category_index, instance_id: dict[str, int]) -> tuple[np.ndarray, np.ndarray]:
        """((P,) uint8 semantic, (P,) uint16 panoptic) labels of one lidar frame."""
        world = sensors.world
        global_from_sensor = invert_rigid(sensors.sensor_from_global(frame))
        points_global = transform_points(global_from_sensor, points[:, :3].astype(np.float64))
        centre = world.annotation_translation_m[annotations]
        global_from_box = quat_to_matrix(world.annotation_rotation[annotations])  # (B, 3, 3)
        half_lwh = 0.5 * world.annotation_size_m[annotations][:, [1, 0, 2]]
        local = np.einsum("bji,bnj->bni", global_from_box, points_global[None] - centre[:, None, :])
        inside = points_in_boxes(local, half_lwh)  # (B, P)
        instances = world.annotation_instance[annotations]
        box_index = np.asarray(category_index)[instances]  # (B,)
        first_box = np.where(inside.any(axis=0), inside.argmax(axis=0), -1)
        semantic = np.where(first_box >= 0, box_index[np.maximum(first_box, 0)], self.ground_index).astype(np.uint8)
        # Panoptic, as generate_panoptic_labels: a box claims the points of its own class inside it.
        claims = inside & (box_index[:, None] == semantic[None, :].astype(np.int64))
        ids = np.array([instance_id[str(instance_tokens[i])] for i in instances], dtype=np.int64)
        panoptic = semantic.astype(np.int64) * 1000 + (claims * ids[:, None]).sum(axis=0)
        n_claims = claims.sum(axis=0)
        panoptic[n_claims > 1] = 0
        thing = (semantic > 0) & (semantic < STUFF_START_INDEX)
        panoptic[thing & (panoptic % 1000 == 0)] = 0
        return semantic, panoptic.astype(np.uint16)

    def _write(self, token: str, semantic: np.ndarray, panoptic: np.ndarray) -> None:
        lidarseg = f"lidarseg/{self.version}/{token}_lidarseg.bin"
        panoptic_file = f"panoptic/{self.version}/{token}_panoptic.npz"
        semantic.tofile(self.dataroot / lidarseg)
        np.savez_compressed(self.dataroot / panoptic_file, data=panoptic)
        self.lidarseg.append({"token": token, "sample_data_token": token, "filename": lidarseg})
        self.panoptic.append({"token": token, "sample_data_token": token, "filename": panoptic_file})

    def close(self) -> None:
        for name, records in (("lidarseg", self.lidarseg), ("panoptic", self.panoptic)):
            (self.table_dir / f"{name}.json").write_text(json.dumps(records, indent=2) + "\n")
