"""The lidarseg / panoptic queries of nuparquet.queries.points against numpy over the label files themselves
(`lidarseg/*.bin`: one uint8 class index a point; `panoptic/*.npz`: one uint16 `index * 1000 + instance id`), on
the labelled synthetic set's cached conversion, in the test's process; and points_in_boxes against the
devkit's points_in_box over the same lidar keyframes. The devkit comparisons of the same
queries are in tests/parity/test_points_queries_devkit.py (on a conversion of their own)."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest

import nuparquet
from conftest import SYNTH_VERSION


@pytest.fixture(scope="module")
def ds(labelled_out):
    return nuparquet.open(labelled_out)


@pytest.fixture(scope="module")
def source(labelled_root):
    """The JSON tables the expectations need, and each labelled keyframe's labels read with numpy."""
    def table(name):
        return json.loads((labelled_root / SYNTH_VERSION / f"{name}.json").read_text())

    scene_name = {s["token"]: s["name"] for s in table("scene")}
    sample_scene = {s["token"]: scene_name[s["scene_token"]] for s in table("sample")}
    sample_data = {sd["token"]: sd for sd in table("sample_data")}
    frames = {}  # sample_data token -> (scene_name, sample_token, timestamp)
    for token, sd in sample_data.items():
        frames[token] = (sample_scene[sd["sample_token"]], sd["sample_token"], sd["timestamp"])
    lidarseg = {r["sample_data_token"]: np.fromfile(labelled_root / r["filename"], dtype=np.uint8)
                for r in table("lidarseg")}
    panoptic = {r["sample_data_token"]: np.load(labelled_root / r["filename"])["data"].astype(np.int64)
                for r in table("panoptic")}
    names = {c["index"]: c["name"] for c in table("category") if c.get("index") is not None}
    return {"frames": frames, "lidarseg": lidarseg, "panoptic": panoptic, "names": names,
            "scenes": sorted(scene_name.values())}


def _class_labels(source, kind: str, token: str) -> np.ndarray:
    labels = source[kind][token]
    return labels if kind == "lidarseg" else labels // 1000


@pytest.mark.parametrize("kind", ["lidarseg", "panoptic"])
def test_class_counts_equal_numpy_bincounts_of_the_label_files_in_index_order(ds, source, kind):
    from nuparquet.queries.points import lidarseg_class_counts

    counts = Counter()
    for token in source[kind]:
        counts.update(dict(zip(*np.unique(_class_labels(source, kind, token), return_counts=True))))
    expected = [(index, source["names"][index], int(counts.get(index, 0))) for index in sorted(source["names"])]
    ours = lidarseg_class_counts(ds, source=kind).collect()
    assert ours.columns == ["index", "name", "points"]
    assert list(ours.iter_rows()) == expected
    assert len(expected) == 32 and sum(n for *_, n in expected) > 0 and sum(n == 0 for *_, n in expected) > 0


@pytest.mark.parametrize("kind", ["lidarseg", "panoptic"])
def test_sample_counts_equal_numpy_counts_of_each_label_file(ds, source, kind):
    from nuparquet.queries.points import sample_lidarseg_counts

    expected = []
    for token in source[kind]:
        scene, sample, _ = source["frames"][token]
        for index, n in zip(*np.unique(_class_labels(source, kind, token), return_counts=True)):
            expected.append((scene, sample, token, int(index), source["names"][int(index)], int(n)))
    expected.sort(key=lambda row: (row[0], row[1], row[3]))
    ours = sample_lidarseg_counts(ds, source=kind).collect()
    assert ours.columns == ["scene_name", "sample_token", "sample_data_token", "index", "name", "points"]
    assert list(ours.iter_rows()) == expected
    assert len({row[1] for row in expected}) == 6


def _instances(source, scene: str | None = None) -> list[tuple]:
    """(scene_name, sample_data_token, timestamp, index, name, instance_id, points) per instance and frame."""
    rows = []
    for token, labels in source["panoptic"].items():
        scene_name, _, timestamp = source["frames"][token]
        if scene is not None and scene_name != scene:
            continue
        for label, n in zip(*np.unique(labels[labels % 1000 > 0], return_counts=True)):
            index = int(label) // 1000
            rows.append((scene_name, token, timestamp, index, source["names"][index], int(label) % 1000, int(n)))
    return sorted(rows, key=lambda row: (row[0], row[2], row[3], row[5]))


def test_panoptic_instances_of_one_scene_equal_numpy_over_its_label_files(ds, source):
    from nuparquet.queries.points import panoptic_instances

    scene = source["scenes"][1]
    expected = _instances(source, scene)
    ours = panoptic_instances(ds, scene=scene).collect()
    assert ours.columns == ["scene_name", "sample_data_token", "timestamp", "index", "name", "instance_id", "points"]
    assert list(ours.iter_rows()) == expected
    assert expected and len(expected) < len(_instances(source))  # the other scene has instances too
    assert list(panoptic_instances(ds).collect().iter_rows()) == _instances(source)


def test_panoptic_instance_stats_and_per_frame_equal_numpy(ds, source):
    from nuparquet.queries.points import panoptic_instance_stats, panoptic_instances_per_frame

    rows = _instances(source)
    frames_of = Counter((scene, index, instance) for scene, _, _, index, _, instance, _ in rows)
    expected = {}
    for index in sorted({row[3] for row in rows}):
        frames = np.array([n for (_, i, _), n in frames_of.items() if i == index], dtype=float)
        points = np.array([row[6] for row in rows if row[3] == index], dtype=float)
        expected[index] = (source["names"][index], len(frames), frames.mean(), frames.std(), points.mean(),
                           points.std())
    ours = panoptic_instance_stats(ds).collect()
    assert ours["index"].to_list() == sorted(expected) and len(expected) > 3
    for row in ours.iter_rows(named=True):
        name, instances, *numbers = expected[row["index"]]
        assert (row["name"], row["instances"]) == (name, instances)
        assert [row["frames_per_instance_mean"], row["frames_per_instance_std"], row["points_per_instance_mean"],
                row["points_per_instance_std"]] == pytest.approx(numbers, rel=1e-12)
    assert any(n > 1 for n in frames_of.values())  # instances seen in several frames

    per_frame = np.array(list(Counter(row[1] for row in rows).values()), dtype=float)
    assert panoptic_instances_per_frame(ds).collect().row(0) == pytest.approx((per_frame.mean(), per_frame.std()),
                                                                              rel=1e-12)
    assert per_frame.std() > 0


def test_points_in_boxes_are_the_devkits_points_in_box_over_each_annotations_lidar_keyframe(ds, labelled_root):
    """`points_in_boxes` (not a label query, but a query of the same points): one row per annotation, counted in the
    LIDAR_TOP keyframe of its sample, as the devkit counts it: `points_in_box` of the box moved into the sensor
    frame (`get_sample_data`'s moves, with the keyframe's ego pose and calibration) over `LidarPointCloud.from_file`."""
    from nuscenes.utils.data_classes import Box, LidarPointCloud
    from nuscenes.utils.geometry_utils import points_in_box
    from pyquaternion import Quaternion

    from nuparquet.queries.points import points_in_boxes

    def table(name):
        return {r["token"]: r for r in json.loads((labelled_root / SYNTH_VERSION / f"{name}.json").read_text())}

    sensor, calibration, pose = table("sensor"), table("calibrated_sensor"), table("ego_pose")
    keyframe = {sd["sample_token"]: sd for sd in table("sample_data").values() if sd["is_key_frame"]
                and sensor[calibration[sd["calibrated_sensor_token"]]["sensor_token"]]["channel"] == "LIDAR_TOP"}
    clouds = {}
    expected = {}
    for token, annotation in table("sample_annotation").items():
        sd = keyframe[annotation["sample_token"]]
        if sd["token"] not in clouds:
            clouds[sd["token"]] = LidarPointCloud.from_file(str(labelled_root / sd["filename"])).points[:3]
        box = Box(annotation["translation"], annotation["size"], Quaternion(annotation["rotation"]))
        for moved in (pose[sd["ego_pose_token"]], calibration[sd["calibrated_sensor_token"]]):
            box.translate(-np.array(moved["translation"]))
            box.rotate(Quaternion(moved["rotation"]).inverse)
        expected[token] = (sd["token"], int(points_in_box(box, clouds[sd["token"]]).sum()), annotation["num_lidar_pts"])
    ours = points_in_boxes(ds)
    assert ours.columns == ["annotation_token", "sample_data_token", "category_name", "points_in_box", "num_lidar_pts"]
    assert sorted(ours["annotation_token"].to_list()) == sorted(expected)  # one row per annotation, no sweep
    got = {row[0]: (row[1], row[3], row[4]) for row in ours.iter_rows()}
    assert got == expected
    assert sum(n for _, n, _ in expected.values()) > 0 and len(clouds) > 3
