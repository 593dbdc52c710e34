"""Folders of the shapes nuScenes-format data committed to public repositories takes (issue 27, part 1), built from
the generator's output by trimming and editing its JSON, and their dangling references counted in plain Python.

Shared by tests/conversion/test_trimmed_extracts.py and tests/parity/test_trimmed_devkit.py. The expectation
(`expected_findings`) walks a hand-written list of the nuScenes schema's keys (`REFERENCES`, from the devkit's
schema documentation) over the JSON records, independently of nuparquet's schema walk.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from conftest import SYNTH_VERSION

VERSION = SYNTH_VERSION

# (table, field, target table, is a list, "" means none). The keys of the nuScenes schema, and those of nuImages'
# 2D tables (object_ann, surface_ann) found beside them.
REFERENCES = [
    ("calibrated_sensor", "sensor_token", "sensor", False, False),
    ("instance", "category_token", "category", False, False),
    ("instance", "first_annotation_token", "sample_annotation", False, False),
    ("instance", "last_annotation_token", "sample_annotation", False, False),
    ("map", "log_tokens", "log", True, False),
    ("sample", "prev", "sample", False, True),
    ("sample", "next", "sample", False, True),
    ("sample", "scene_token", "scene", False, False),
    ("sample_annotation", "sample_token", "sample", False, False),
    ("sample_annotation", "instance_token", "instance", False, False),
    ("sample_annotation", "visibility_token", "visibility", False, True),
    ("sample_annotation", "attribute_tokens", "attribute", True, False),
    ("sample_annotation", "prev", "sample_annotation", False, True),
    ("sample_annotation", "next", "sample_annotation", False, True),
    ("sample_data", "sample_token", "sample", False, False),
    ("sample_data", "ego_pose_token", "ego_pose", False, False),
    ("sample_data", "calibrated_sensor_token", "calibrated_sensor", False, False),
    ("sample_data", "prev", "sample_data", False, True),
    ("sample_data", "next", "sample_data", False, True),
    ("scene", "log_token", "log", False, False),
    ("scene", "first_sample_token", "sample", False, False),
    ("scene", "last_sample_token", "sample", False, False),
]
REFERENCES_2D = [
    ("object_ann", "sample_data_token", "sample_data", False, False),
    ("object_ann", "category_token", "category", False, False),
    ("object_ann", "attribute_tokens", "attribute", True, False),
    ("surface_ann", "sample_data_token", "sample_data", False, False),
    ("surface_ann", "category_token", "category", False, False),
]
COUNTS = [("scene", "nbr_samples", "sample", "scene_token"), ("instance", "nbr_annotations", "sample_annotation",
                                                              "instance_token")]
ABSENT = "0bad" * 8  # a token of no record


def load(folder: Path, table: str) -> list[dict]:
    return json.loads((folder / f"{table}.json").read_text())


def save(folder: Path, table: str, records: list[dict]) -> None:
    (folder / f"{table}.json").write_text(json.dumps(records, indent=0))


def scene_samples(folder: Path, scene_index: int = 0) -> list[dict]:
    """The samples of one scene, in time order."""
    scene = load(folder, "scene")[scene_index]
    return sorted((s for s in load(folder, "sample") if s["scene_token"] == scene["token"]), key=lambda s: s["timestamp"])


def one_keyframe(folder: Path) -> None:
    """One keyframe (the third) of the first scene: its sample, its sample_data (keyframes and the sweeps that name
    it), the ego poses of the keyframes only and its annotations, beside the full instance, calibrated_sensor, log
    and map tables; the scene table holds that scene only."""
    keep = scene_samples(folder)[2]
    save(folder, "scene", [s for s in load(folder, "scene") if s["token"] == keep["scene_token"]])
    save(folder, "sample", [keep])
    sample_data = [d for d in load(folder, "sample_data") if d["sample_token"] == keep["token"]]
    save(folder, "sample_data", sample_data)
    poses = {d["ego_pose_token"] for d in sample_data if d["is_key_frame"]}
    save(folder, "ego_pose", [p for p in load(folder, "ego_pose") if p["token"] in poses])
    save(folder, "sample_annotation", [a for a in load(folder, "sample_annotation") if a["sample_token"] == keep["token"]])


def cut_tail(folder: Path) -> None:
    """The first scene without its last sample: the sample, its keyframes (their ego poses) and its annotations
    are gone, so the scene's last_sample_token and the next pointers lead nowhere; the sweeps before it stay, naming
    a sample that is absent."""
    last = scene_samples(folder)[-1]
    save(folder, "sample", [s for s in load(folder, "sample") if s["token"] != last["token"]])
    sample_data = load(folder, "sample_data")
    gone = {d["token"] for d in sample_data if d["sample_token"] == last["token"] and d["is_key_frame"]}
    poses = {d["ego_pose_token"] for d in sample_data if d["token"] in gone}
    save(folder, "sample_data", [d for d in sample_data if d["token"] not in gone])
    save(folder, "ego_pose", [p for p in load(folder, "ego_pose") if p["token"] not in poses])
    save(folder, "sample_annotation", [a for a in load(folder, "sample_annotation") if a["sample_token"] != last["token"]])


def first_annotations_absent(folder: Path) -> None:
    """The annotations of the first scene's first sample are gone: their instances' first_annotation_token and the
    next annotations' prev lead nowhere."""
    first = scene_samples(folder)[0]
    save(folder, "sample_annotation", [a for a in load(folder, "sample_annotation") if a["sample_token"] != first["token"]])


def pre_lidarseg_category(folder: Path) -> None:
    """category.json as released before nuScenes-lidarseg: no `index`."""
    save(folder, "category", [{k: v for k, v in c.items() if k != "index"} for c in load(folder, "category")])


def category_name_field(folder: Path) -> None:
    """Each sample_annotation carries an extra `category_name` (as some exports write it), after its own fields."""
    names = {c["token"]: c["name"] for c in load(folder, "category")}
    category_of = {i["token"]: names[i["category_token"]] for i in load(folder, "instance")}
    annotations = load(folder, "sample_annotation")
    for a in annotations:
        a["category_name"] = category_of[a["instance_token"]]
    save(folder, "sample_annotation", annotations)


def empty_intrinsics(folder: Path) -> None:
    """`camera_intrinsic: []` on the lidar and radar calibrations, as nuScenes writes them (the generator does too)."""
    modality = {s["token"]: s["modality"] for s in load(folder, "sensor")}
    calibrations = load(folder, "calibrated_sensor")
    for c in calibrations:
        if modality[c["sensor_token"]] != "camera":
            c["camera_intrinsic"] = []
    save(folder, "calibrated_sensor", calibrations)


def map_log_tokens_absent(folder: Path) -> None:
    """Each map names, after its own logs, a log that is absent (the logs of other extracts)."""
    maps = load(folder, "map")
    for i, m in enumerate(maps):
        m["log_tokens"] = m["log_tokens"] + [f"{i:04d}" + "feed" * 7]
    save(folder, "map", maps)


def worded_visibility(folder: Path) -> None:
    """Visibility tokens spelled none|partial|most|full instead of 1..4 (the levels stay v0-40 ... v80-100)."""
    words = {"1": "none", "2": "partial", "3": "most", "4": "full"}
    visibility = load(folder, "visibility")
    for v in visibility:
        v["token"] = words[v["token"]]
    save(folder, "visibility", visibility)
    annotations = load(folder, "sample_annotation")
    for a in annotations:
        a["visibility_token"] = words.get(a["visibility_token"], a["visibility_token"])
    save(folder, "sample_annotation", annotations)


def tables_2d(folder: Path) -> None:
    """nuImages' 2D tables beside the 3D ones: object_ann (bbox, RLE mask, attributes) on the camera keyframes of the
    first sample, surface_ann on two of them; one object_ann names a sample_data that is absent, as in a trimmed
    extract."""
    modality = {s["token"]: s["modality"] for s in load(folder, "sensor")}
    sensor_of = {c["token"]: c["sensor_token"] for c in load(folder, "calibrated_sensor")}
    first = scene_samples(folder)[0]
    cameras = [d for d in load(folder, "sample_data") if d["sample_token"] == first["token"] and d["is_key_frame"]
               and modality[sensor_of[d["calibrated_sensor_token"]]] == "camera"]
    categories = [c["token"] for c in load(folder, "category")]
    attributes = [a["token"] for a in load(folder, "attribute")]
    objects = [{"token": f"{i:032x}", "category_token": categories[i % len(categories)],
                "attribute_tokens": [attributes[i % len(attributes)]] if i % 2 else [],
                "bbox": [100 + i, 200, 300 + i, 420], "mask": {"size": [900, 1600], "counts": f"Yc0{i}2N1O"},
                "sample_data_token": d["token"]} for i, d in enumerate(cameras)]
    objects.append({"token": "f" * 32, "category_token": categories[0], "attribute_tokens": [],
                    "bbox": [0, 0, 10, 10], "mask": {"size": [900, 1600], "counts": "P0"}, "sample_data_token": ABSENT})
    save(folder, "object_ann", objects)
    save(folder, "surface_ann", [{"token": f"{i + 100:032x}", "category_token": categories[-1],
                                  "mask": {"size": [900, 1600], "counts": "abc"}, "sample_data_token": d["token"]}
                                 for i, d in enumerate(cameras[:2])])


def devkit_refuses(folder: Path) -> None:
    """What the devkit cannot load (KeyError in NuScenes.__init__): the calibrations of one radar, one instance with
    annotations and one attribute in use are absent."""
    radar = next(s["token"] for s in load(folder, "sensor") if s["modality"] == "radar")
    save(folder, "calibrated_sensor", [c for c in load(folder, "calibrated_sensor") if c["sensor_token"] != radar])
    annotations = load(folder, "sample_annotation")
    save(folder, "instance", [i for i in load(folder, "instance") if i["token"] != annotations[0]["instance_token"]])
    used = next(a["attribute_tokens"][0] for a in annotations if a["attribute_tokens"])
    save(folder, "attribute", [a for a in load(folder, "attribute") if a["token"] != used])


def everything(folder: Path) -> None:
    """A trimmed extract with every other shape at once."""
    tables_2d(folder)
    category_name_field(folder)
    one_keyframe(folder)
    for edit in (pre_lidarseg_category, empty_intrinsics, map_log_tokens_absent, worded_visibility):
        edit(folder)


@dataclass(frozen=True)
class Shape:
    name: str
    edit: Callable[[Path], None]
    strict: str  # "exact" (converts, comes back exactly) or "refused"
    devkit_loads: bool = True  # nuscenes-devkit's NuScenes loads the folder


SHAPES = [
    Shape("one_keyframe", one_keyframe, "refused"),
    Shape("cut_tail", cut_tail, "refused"),
    Shape("first_annotations_absent", first_annotations_absent, "refused"),
    Shape("pre_lidarseg_category", pre_lidarseg_category, "exact"),
    Shape("category_name_field", category_name_field, "exact"),
    Shape("empty_intrinsics", empty_intrinsics, "exact"),
    Shape("map_log_tokens_absent", map_log_tokens_absent, "refused"),
    Shape("worded_visibility", worded_visibility, "exact"),
    Shape("tables_2d", tables_2d, "exact"),
    Shape("everything", everything, "refused"),
    Shape("devkit_refuses", devkit_refuses, "refused", devkit_loads=False),
]


def make(pristine: Path, root: Path, shape: Shape) -> Path:
    shutil.copytree(pristine, root)
    shape.edit(root / VERSION)
    return root


def tables_of(folder: Path) -> dict[str, list[dict]]:
    return {p.stem: json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))}


def expected_findings(folder: Path, *, with_2d: bool = True) -> tuple[list[tuple], list[tuple]]:
    """(dangling references as (table, field, target, record index, token, reference, position), count mismatches
    as (table, field, target, record index, token, stated, actual)), in plain Python over the JSON records."""
    tables = tables_of(folder)
    dangling = []
    for table, field, target, is_list, empty_ok in REFERENCES + (REFERENCES_2D if with_2d else []):
        if table not in tables or target not in tables:
            continue
        known = {r["token"] for r in tables[target]}
        for i, record in enumerate(tables[table]):
            values = list(enumerate(record[field])) if is_list else [(None, record[field])]
            for position, value in values:
                if not (empty_ok and value == "") and value not in known:
                    dangling.append((table, field, target, i, record.get("token"), value, position))
    mismatches = []
    for table, field, referring, key in COUNTS:
        for i, record in enumerate(tables[table]):
            actual = sum(r[key] == record["token"] for r in tables[referring])
            if record[field] != actual:
                mismatches.append((table, field, referring, i, record["token"], record[field], actual))
    return dangling, mismatches


def same_json(a, b, where: str) -> None:
    """Equal JSON values, types (1 is not 1.0), key order and NaN included."""
    assert type(a) is type(b), where
    if isinstance(a, dict):
        assert list(a) == list(b), f"{where}: key order"
        for k in a:
            same_json(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            same_json(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and math.isnan(a):
        assert math.isnan(b), where
    else:
        assert a == b, where
