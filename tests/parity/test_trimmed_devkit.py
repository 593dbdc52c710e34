"""Trimmed extracts and the other shapes of issue 27 (`trimmed_shapes`) against nuscenes-devkit: the devkit loads
the same folders nuparquet converts with `--allow-dangling` (all but the shape it cannot load), and for every row
whose joins have partners the derived datasets say what the devkit answers; where the devkit's answer is a KeyError
(a token that names no record) the column is null."""

from __future__ import annotations

import math
import os

import numpy as np
import polars as pl
import pytest

from nuparquet.conversion import convert
from trimmed_shapes import SHAPES, VERSION, make

os.environ.setdefault("MPLBACKEND", "Agg")
MISSING = object()


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    from nuparquet.synth import synthesize

    return synthesize(tmp_path_factory.mktemp("trim-devkit") / "data", scenes=2, samples_per_scene=5, seed=21,
                      version=VERSION)


@pytest.fixture(scope="module", params=[s.name for s in SHAPES if s.devkit_loads])
def case(request, pristine, tmp_path_factory, devkit):
    shape = next(s for s in SHAPES if s.name == request.param)
    root = make(pristine, tmp_path_factory.mktemp(shape.name) / "data", shape)
    out = tmp_path_factory.mktemp(f"{shape.name}-out") / "out"
    convert(root, VERSION, out, allow_dangling=True)
    return out, devkit.NuScenes(version=VERSION, dataroot=str(root), verbose=False)


def answer(question):
    """The devkit's answer, or MISSING where it raises KeyError (a token of no record)."""
    try:
        return question()
    except KeyError:
        return MISSING


def expect(value):
    return None if value is MISSING else value


def rows(out, dataset: str) -> dict[str, dict]:
    return {r["token"]: r for r in pl.read_parquet(out / dataset / "*.parquet").iter_rows(named=True)}


def test_the_devkit_cannot_load_what_only_allow_dangling_converts(pristine, tmp_path, devkit):
    shape = next(s for s in SHAPES if not s.devkit_loads)
    root = make(pristine, tmp_path / "data", shape)
    with pytest.raises(KeyError):
        devkit.NuScenes(version=VERSION, dataroot=str(root), verbose=False)
    convert(root, VERSION, tmp_path / "out", allow_dangling=True)  # nuparquet converts it, with nulls


def test_frames_equal_the_devkit_where_it_answers(case):
    out, nusc = case
    frames = rows(out, "frames")
    assert len(frames) == len(nusc.sample_data)
    answered = 0
    for sd in nusc.sample_data:
        row = frames[sd["token"]]
        assert row["channel"] == sd["channel"] and row["modality"] == sd["sensor_modality"]
        pose = answer(lambda: nusc.get("ego_pose", sd["ego_pose_token"]))
        assert row["ego_translation"] == expect(pose if pose is MISSING else pose["translation"])
        assert row["ego_rotation"] == expect(pose if pose is MISSING else pose["rotation"])
        calib = nusc.get("calibrated_sensor", sd["calibrated_sensor_token"])
        assert row["sensor_translation"] == calib["translation"] and (row["camera_intrinsic"] or []) == [
            x for r in calib["camera_intrinsic"] for x in r]
        scene = answer(lambda: nusc.get("scene", nusc.get("sample", sd["sample_token"])["scene_token"]))
        assert row["scene_name"] == expect(scene if scene is MISSING else scene["name"])
        location = answer(lambda: nusc.get("log", scene["log_token"])["location"]) if scene is not MISSING else MISSING
        assert row["log_location"] == expect(location)
        answered += pose is not MISSING and scene is not MISSING
    assert answered > 0


def test_annotations_equal_the_devkit_where_it_answers(case):
    out, nusc = case
    annotations = rows(out, "annotations")
    assert len(annotations) == len(nusc.sample_annotation)
    seen = {"velocity": 0, "nan": 0, "raises": 0}
    for record in nusc.sample_annotation:
        row = annotations[record["token"]]
        assert row["category_name"] == record["category_name"]  # the devkit's, whatever field the source adds
        assert row["timestamp"] == expect(answer(lambda: nusc.get("sample", record["sample_token"])["timestamp"]))
        assert row["attribute_names"] == [expect(answer(lambda t=t: nusc.get("attribute", t)["name"]))
                                          for t in record["attribute_tokens"]]
        velocity = answer(lambda: nusc.box_velocity(record["token"]))
        if velocity is MISSING:
            assert row["velocity"] is None
            seen["raises"] += 1
        elif np.isnan(velocity).any():
            assert all(math.isnan(v) for v in row["velocity"])
            seen["nan"] += 1
        else:
            np.testing.assert_allclose(row["velocity"], velocity, rtol=0, atol=1e-9)
            seen["velocity"] += 1
    assert seen["velocity"] + seen["nan"] > 0


def test_scenes_and_instances_equal_the_devkit_where_it_answers(case):
    out, nusc = case
    scenes = rows(out, "scenes")
    assert len(scenes) == len(nusc.scene)
    for scene in nusc.scene:
        row = scenes[scene["token"]]
        log = nusc.get("log", scene["log_token"])
        assert (row["log_location"], row["vehicle"], row["logfile"]) == (log["location"], log["vehicle"], log["logfile"])
        for end in ("first", "last"):
            assert row[f"{end}_timestamp"] == expect(answer(lambda: nusc.get("sample", scene[f"{end}_sample_token"])["timestamp"]))
    instances = rows(out, "instances")
    assert len(instances) == len(nusc.instance)
    for instance in nusc.instance:
        row = instances[instance["token"]]
        assert row["category_name"] == nusc.get("category", instance["category_token"])["name"]
        for end in ("first", "last"):
            timestamp = answer(lambda: nusc.get("sample", nusc.get("sample_annotation", instance[f"{end}_annotation_token"])
                                                ["sample_token"])["timestamp"])
            assert row[f"{end}_timestamp"] == expect(timestamp)
