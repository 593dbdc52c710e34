"""The 13 nuScenes JSON tables of the synthetic dataset, streamed to disk scene by scene.

Layout: each file is byte-identical to `json.dumps(records, indent=0)` (the layout of the real nuScenes
tables: one field per line, keys in the real files' order). The large tables (sample_data, ego_pose,
sample_annotation: ~2.6M, 2.6M and 1.2M records at trainval scale) are formatted with %-templates from
column lists rather than through dicts and `json.dumps`, which is several times faster and never holds more
than one scene in memory. `%r` of a Python float is exactly what `json` writes for it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nuparquet.synth.plan import LogPlan
from nuparquet.synth.taxonomy import ATTRIBUTES, CATEGORIES, VISIBILITIES, Channel
from nuparquet.synth.tokens import name_token, random_tokens
from nuparquet.synth.world import SceneWorld

TABLES = ("attribute", "calibrated_sensor", "category", "ego_pose", "instance", "log", "map", "sample",
          "sample_annotation", "sample_data", "scene", "sensor", "visibility")

_SAMPLE = '{\n"token": "%s",\n"timestamp": %d,\n"prev": "%s",\n"next": "%s",\n"scene_token": "%s"\n}'
_SAMPLE_DATA = (
    '{\n"token": "%s",\n"sample_token": "%s",\n"ego_pose_token": "%s",\n"calibrated_sensor_token": "%s",\n'
    '"timestamp": %d,\n"fileformat": "%s",\n"is_key_frame": %s,\n"height": %d,\n"width": %d,\n"filename": "%s",\n'
    '"prev": "%s",\n"next": "%s"\n}'
)
_EGO_POSE = ('{\n"token": "%s",\n"timestamp": %d,\n"rotation": [\n%r,\n%r,\n%r,\n%r\n],\n'
             '"translation": [\n%r,\n%r,\n%r\n]\n}')
_SAMPLE_ANNOTATION = (
    '{\n"token": "%s",\n"sample_token": "%s",\n"instance_token": "%s",\n"visibility_token": "%s",\n'
    '"attribute_tokens": %s,\n"translation": [\n%r,\n%r,\n%r\n],\n"size": [\n%r,\n%r,\n%r\n],\n'
    '"rotation": [\n%r,\n%r,\n%r,\n%r\n],\n"prev": "%s",\n"next": "%s",\n"num_lidar_pts": %d,\n'
    '"num_radar_pts": %d\n}'
)
_INSTANCE = ('{\n"token": "%s",\n"category_token": "%s",\n"nbr_annotations": %d,\n"first_annotation_token": "%s",\n'
             '"last_annotation_token": "%s"\n}')

CATEGORY_TOKENS = [name_token("category", c.name) for c in CATEGORIES]
ATTRIBUTE_TOKENS = [name_token("attribute", name) for name, _ in ATTRIBUTES]


def map_token(location: str) -> str:
    return name_token("map", location)


def sensor_tokens(channels: tuple[Channel, ...]) -> list[str]:
    return [name_token("sensor", c.name) for c in channels]


class TableWriter:
    """Streams records into one table file; the result equals `json.dumps(all_records, indent=0)`."""

    def __init__(self, path: Path):
        self._file = open(path, "w", encoding="utf-8")  # noqa: SIM115 - closed in close()
        self._file.write("[")
        self.count = 0

    def write(self, records: list[str]) -> None:
        """Append records already formatted as `json.dumps(record, indent=0)`."""
        if records:
            self._file.write(("\n" if self.count == 0 else ",\n") + ",\n".join(records))
            self.count += len(records)

    def write_dicts(self, records: list[dict]) -> None:
        self.write([json.dumps(r, indent=0) for r in records])

    def close(self) -> None:
        self._file.write("\n]" if self.count else "]")
        self._file.close()


@dataclass(frozen=True)
class SceneTokens:
    """Tokens of one scene's records. Index -1 of the padded arrays is "" (no prev/next)."""

    scene: str
    sample: np.ndarray  # (K + 1,) str, last ""
    frame: np.ndarray  # (M + 1,) str: sample_data and ego_pose share them
    instance: np.ndarray  # (I,)
    annotation: np.ndarray  # (A + 1,)
    calibrated_sensor: np.ndarray  # (C,)

    @classmethod
    def draw(cls, rng: np.random.Generator, world: SceneWorld, n_channels: int) -> SceneTokens:
        tl = world.timeline
        counts = [1, tl.sample_timestamp_us.size, tl.frame_timestamp_us.size, world.instance_category.size,
                  world.annotation_instance.size, n_channels]
        tokens = np.array(random_tokens(rng, sum(counts)) + [""])
        bounds = np.cumsum([0] + counts)
        part = [tokens[bounds[i]:bounds[i + 1]] for i in range(len(counts))]
        empty = np.array([""])
        return cls(scene=str(part[0][0]), sample=np.r_[part[1], empty], frame=np.r_[part[2], empty],
                   instance=part[3], annotation=np.r_[part[4], empty], calibrated_sensor=part[5])


def frame_filenames(world: SceneWorld, logfile: str, channels: tuple[Channel, ...]) -> list[str]:
    """Relative sensor file path of every frame: samples/<CH>/<logfile>__<CH>__<timestamp_us>.<ext>, sweeps/..."""
    tl = world.timeline
    names = [c.name for c in channels]
    extensions = [c.extension for c in channels]
    return [f"{'samples' if key else 'sweeps'}/{names[c]}/{logfile}__{names[c]}__{t}{extensions[c]}"
            for c, t, key in zip(tl.frame_channel.tolist(), tl.frame_timestamp_us.tolist(),
                                 tl.frame_is_key_frame.tolist())]


def scene_records(world: SceneWorld, tokens: SceneTokens, log: LogPlan, scene_name: str,
                  filenames: list[str]) -> dict[str, list[str]]:
    """Formatted records of every per-scene table: scene, sample, sample_data, ego_pose, calibrated_sensor,
    instance, sample_annotation."""
    tl = world.timeline
    k = tl.sample_timestamp_us.size
    sample_index = np.arange(k)
    samples = [_SAMPLE % row for row in zip(
        tokens.sample[:k].tolist(), tl.sample_timestamp_us.tolist(),
        tokens.sample[np.where(sample_index > 0, sample_index - 1, -1)].tolist(),
        tokens.sample[np.where(sample_index < k - 1, sample_index + 1, -1)].tolist(),
        [tokens.scene] * k)]
    scene = {"token": tokens.scene, "log_token": log.token, "nbr_samples": k,
             "first_sample_token": str(tokens.sample[0]), "last_sample_token": str(tokens.sample[k - 1]),
             "name": scene_name, "description": world.description}

    rig = log.rig
    sensors = sensor_tokens(rig.channels)
    calibrated = []
    for c, channel in enumerate(rig.channels):
        calibrated.append({
            "token": str(tokens.calibrated_sensor[c]), "sensor_token": sensors[c],
            "translation": rig.ego_from_sensor_translation_m[c].tolist(),
            "rotation": rig.ego_from_sensor_rotation[c].tolist(),
            "camera_intrinsic": rig.intrinsic[c].tolist() if channel.modality == "camera" else [],
        })

    m = tl.frame_timestamp_us.size
    frame_tokens = tokens.frame[:m].tolist()
    channel = tl.frame_channel
    width_px, height_px = np.array([c.size_px for c in rig.channels], dtype=np.int64)[channel].T  # 0 for non-cameras
    fileformats = [c.fileformat for c in rig.channels]
    sample_data = [_SAMPLE_DATA % row for row in zip(
        frame_tokens, tokens.sample[tl.frame_sample_index].tolist(), frame_tokens,
        tokens.calibrated_sensor[channel].tolist(), tl.frame_timestamp_us.tolist(),
        [fileformats[c] for c in channel.tolist()],
        np.where(tl.frame_is_key_frame, "true", "false").tolist(),
        height_px.tolist(), width_px.tolist(),
        filenames, tokens.frame[tl.frame_prev].tolist(), tokens.frame[tl.frame_next].tolist())]
    _check_finite(world.ego_rotation, world.ego_translation_m)
    ego_pose = [_EGO_POSE % row for row in zip(
        frame_tokens, tl.frame_timestamp_us.tolist(), *world.ego_rotation.T.tolist(),
        *world.ego_translation_m.T.tolist())]

    n_ann = world.annotation_instance.size
    first = world.instance_first_annotation
    last = first + world.instance_n_annotations - 1
    instances = [_INSTANCE % row for row in zip(
        tokens.instance.tolist(), [CATEGORY_TOKENS[c] for c in world.instance_category.tolist()],
        world.instance_n_annotations.tolist(), tokens.annotation[first].tolist(),
        tokens.annotation[last].tolist())]
    attribute_json = ['[\n"%s"\n]' % t for t in ATTRIBUTE_TOKENS] + ["[]"]  # index -1: no attribute
    ann_index = np.arange(n_ann)
    _check_finite(world.annotation_translation_m, world.annotation_size_m, world.annotation_rotation)
    annotations = [_SAMPLE_ANNOTATION % row for row in zip(
        tokens.annotation[:n_ann].tolist(), tokens.sample[world.annotation_sample].tolist(),
        tokens.instance[world.annotation_instance].tolist(), world.annotation_visibility.astype(str).tolist(),
        [attribute_json[a] for a in world.annotation_attribute.tolist()],
        *world.annotation_translation_m.T.tolist(), *world.annotation_size_m.T.tolist(),
        *world.annotation_rotation.T.tolist(),
        tokens.annotation[np.where(world.annotation_has_prev, ann_index - 1, -1)].tolist(),
        tokens.annotation[np.where(world.annotation_has_next, ann_index + 1, -1)].tolist(),
        world.annotation_num_lidar_pts.tolist(), world.annotation_num_radar_pts.tolist())]

    return {
        "scene": [json.dumps(scene, indent=0)], "sample": samples, "sample_data": sample_data,
        "ego_pose": ego_pose, "calibrated_sensor": [json.dumps(r, indent=0) for r in calibrated],
        "instance": instances, "sample_annotation": annotations,
    }


def global_records(logs: list[LogPlan]) -> dict[str, list[dict]]:
    """The tables shared by all scenes: category, attribute, visibility, sensor, log, map."""
    maps: dict[str, list[str]] = {}
    for log in logs:
        maps.setdefault(log.location.name, []).append(log.token)
    return {
        "category": [{"token": t, "name": c.name, "description": c.description, "index": c.index}
                     for t, c in zip(CATEGORY_TOKENS, CATEGORIES)],
        "attribute": [{"token": t, "name": name, "description": description}
                      for t, (name, description) in zip(ATTRIBUTE_TOKENS, ATTRIBUTES)],
        "visibility": [{"description": description, "token": token, "level": level}
                       for token, level, description in VISIBILITIES],
        "sensor": [{"token": t, "channel": c.name, "modality": c.modality}
                   for t, c in zip(sensor_tokens(logs[0].rig.channels), logs[0].rig.channels)],
        "log": [{"token": log.token, "logfile": log.logfile, "vehicle": log.vehicle,
                 "date_captured": log.date_captured, "location": log.location.name} for log in logs],
        "map": [{"category": "semantic_prior", "token": map_token(location),
                 "filename": f"maps/{map_token(location)}.png", "log_tokens": log_tokens}
                for location, log_tokens in maps.items()],
    }


def _check_finite(*arrays: np.ndarray) -> None:
    for array in arrays:
        if not np.isfinite(array).all():  # JSON has no NaN: a generator bug must not produce invalid files
            raise AssertionError("synthetic generator produced a non-finite value")
