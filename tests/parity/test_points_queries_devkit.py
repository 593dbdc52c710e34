"""The lidarseg / panoptic / points-in-boxes queries against the devkit: on synthetic data with labels
(`list_lidarseg_categories`, `get_sample_lidarseg_stats`, the numbers of `list_panoptic_instances`,
`num_lidar_pts`), and points in boxes on the real extract (`points_in_box` over the keyframe cloud)."""

from __future__ import annotations

import re

import numpy as np
import polars as pl
import pytest

from conftest import EXTRACT_VERSION, SYNTH_VERSION


@pytest.fixture(scope="module")
def labelled(labelled_root, tmp_path_factory):
    from nuparquet.conversion import convert

    out = tmp_path_factory.mktemp("labelled-q-out") / "out"
    convert(labelled_root, SYNTH_VERSION, out, sensors=("lidar",), workers=1)
    return labelled_root, out


@pytest.fixture(scope="module")
def nusc(labelled):
    from nuscenes.nuscenes import NuScenes

    return NuScenes(SYNTH_VERSION, str(labelled[0]), verbose=False)


@pytest.fixture(scope="module")
def ds(labelled):
    import nuparquet

    return nuparquet.open(labelled[1])


def _printed_counts(text: str) -> dict[str, int]:
    """{class name: count} from the devkit's lines `idx  name  nbr_points=  1,234` / `n=  1,234`."""
    return {m.group(1): int(m.group(2).replace(",", ""))
            for m in re.finditer(r"^\s*\d+\s+(\S+)\s+(?:nbr_points|n)=\s*([\d,]+)\s*$", text, re.MULTILINE)}


@pytest.mark.parametrize("source", ["lidarseg", "panoptic"])
def test_class_counts_equal_devkit_list_lidarseg_categories(nusc, ds, capsys, source):
    from nuparquet.queries.points import lidarseg_class_counts

    capsys.readouterr()
    nusc.list_lidarseg_categories(sort_by="index", gt_from=source)
    expected = _printed_counts(capsys.readouterr().out)
    ours = lidarseg_class_counts(ds, source=source).collect()
    assert dict(zip(ours["name"], ours["points"])) == expected
    assert len(expected) == 32 and sum(expected.values()) > 0  # every class index of category.json, zeros included


def test_sample_counts_equal_devkit_get_sample_lidarseg_stats(nusc, ds, capsys):
    from nuparquet.queries.points import sample_lidarseg_counts

    ours = sample_lidarseg_counts(ds).collect()
    assert ours["sample_token"].n_unique() == len(nusc.sample) == 6
    for sample in nusc.sample:
        capsys.readouterr()
        nusc.get_sample_lidarseg_stats(sample["token"], sort_by="index")
        expected = _printed_counts(capsys.readouterr().out)
        rows = ours.filter(pl.col("sample_token") == sample["token"])
        assert dict(zip(rows["name"], rows["points"])) == expected, sample["token"]


def test_panoptic_instance_stats_equal_devkit(nusc, ds, labelled):
    from nuscenes.panoptic.panoptic_utils import get_frame_panoptic_instances, get_panoptic_instances_stats
    from nuscenes.utils.data_io import load_bin_file

    from nuparquet.queries.points import panoptic_instance_stats, panoptic_instances_per_frame

    # The inputs list_panoptic_instances builds, from the devkit's own loaders.
    per_scene: dict[str, np.ndarray] = {}
    for frame_id, record in enumerate(nusc.panoptic):
        labels = load_bin_file(str(labelled[0] / record["filename"]), type="panoptic")
        scene = nusc.get("sample", nusc.get("sample_data", record["sample_data_token"])["sample_token"])["scene_token"]
        per_scene[scene] = np.append(per_scene.get(scene, np.empty((0, 4), np.int32)),
                                     get_frame_panoptic_instances(labels, frame_id=frame_id), axis=0)
    expected = get_panoptic_instances_stats(per_scene, nusc.lidarseg_idx2name_mapping)
    ours = panoptic_instance_stats(ds).collect()
    by_name = {row["name"]: row for row in ours.iter_rows(named=True)}
    with_instances = {n: s for n, s in expected["per_category_panoptic_stats"].items() if s["num_instances"]}
    assert set(by_name) == set(with_instances) and len(by_name) > 3  # the devkit adds the others as zeros
    for name, stats in with_instances.items():
        row = by_name[name]
        assert row["instances"] == stats["num_instances"], name
        assert (row["frames_per_instance_mean"], row["frames_per_instance_std"]) == pytest.approx(
            stats["num_frames_per_instance"], rel=1e-12), name
        assert (row["points_per_instance_mean"], row["points_per_instance_std"]) == pytest.approx(
            stats["num_points_per_instance"], rel=1e-12), name
    per_frame = panoptic_instances_per_frame(ds).collect().row(0)
    assert per_frame == pytest.approx(expected["per_frame_panoptic_stats"]["per_frame_num_instances"], rel=1e-12)


def test_points_in_boxes_equal_devkit_and_num_lidar_pts_on_synthetic_data(ds, nusc, labelled):
    from nuscenes.utils.data_classes import LidarPointCloud
    from nuscenes.utils.geometry_utils import points_in_box

    from nuparquet.queries.points import points_in_boxes

    ours = points_in_boxes(ds)
    ours = dict(zip(ours["annotation_token"], ours["points_in_box"]))
    assert len(ours) == len(nusc.sample_annotation)
    alone = 0
    for sample in nusc.sample:
        path, boxes, _ = nusc.get_sample_data(sample["data"]["LIDAR_TOP"])
        cloud = LidarPointCloud.from_file(path).points[:3]
        inside = np.array([points_in_box(box, cloud) for box in boxes]).reshape(len(boxes), -1)
        shared = inside.sum(axis=0) > 1  # points inside two boxes (overlapping boxes)
        for box, mask in zip(boxes, inside):
            assert ours[box.token] == int(mask.sum()), box.token  # the devkit's count
            if not (mask & shared).any():  # the generator put num_lidar_pts points in each box
                assert ours[box.token] == nusc.get("sample_annotation", box.token)["num_lidar_pts"], box.token
                alone += 1
    assert alone > 0.9 * len(ours) and sum(ours.values()) > 0


def test_points_in_boxes_equal_devkit_points_in_box_on_the_real_extract(extract_root, extract_points_out):
    from nuscenes.nuscenes import NuScenes
    from nuscenes.utils.data_classes import LidarPointCloud
    from nuscenes.utils.geometry_utils import points_in_box

    import nuparquet
    from nuparquet.queries.points import points_in_boxes

    ours = points_in_boxes(nuparquet.open(extract_points_out), scene="scene-0916")
    nusc = NuScenes(EXTRACT_VERSION, str(extract_root), verbose=False)
    scene = next(s for s in nusc.scene if s["name"] == "scene-0916")
    expected, token = {}, scene["first_sample_token"]
    while token:
        sample = nusc.get("sample", token)
        path, boxes, _ = nusc.get_sample_data(sample["data"]["LIDAR_TOP"])
        cloud = LidarPointCloud.from_file(path).points[:3]
        expected.update({box.token: int(points_in_box(box, cloud).sum()) for box in boxes})
        token = sample["next"]
    assert dict(zip(ours["annotation_token"], ours["points_in_box"])) == expected
    assert len(expected) == 2424 and sum(expected.values()) > 0


def test_synthetic_panoptic_labels_equal_devkit_generate_panoptic_labels(nusc, labelled, tmp_path):
    from nuscenes.panoptic.generate_panoptic_labels import generate_panoptic_labels

    generate_panoptic_labels(nusc, str(tmp_path))  # from our lidarseg labels and the boxes, as Panoptic nuScenes was made
    compared = 0
    for record in nusc.panoptic:
        ours = np.load(labelled[0] / record["filename"])["data"]
        theirs = np.load(tmp_path / record["filename"])["data"]
        assert ours.dtype == theirs.dtype == np.uint16 and np.array_equal(ours, theirs), record["filename"]
        compared += ours.size
    assert compared > 0 and len(nusc.panoptic) == len(nusc.sample)


def test_synthetic_lidarseg_labels_are_the_category_index_of_the_box_a_point_is_in(nusc, labelled):
    from nuscenes.utils.data_classes import LidarPointCloud
    from nuscenes.utils.geometry_utils import points_in_box

    in_boxes = 0
    for sample in nusc.sample:
        token = sample["data"]["LIDAR_TOP"]
        path, boxes, _ = nusc.get_sample_data(token)
        cloud = LidarPointCloud.from_file(path).points[:3]
        labels = np.fromfile(labelled[0] / nusc.get("lidarseg", token)["filename"], dtype=np.uint8)
        inside = np.array([points_in_box(box, cloud) for box in boxes]).reshape(len(boxes), -1)
        for box, mask in zip(boxes, inside):
            alone = mask & (inside.sum(axis=0) == 1)
            assert (labels[alone] == nusc.lidarseg_name2idx_mapping[box.name]).all(), box.token
            in_boxes += int(alone.sum())
        outside = ~inside.any(axis=0)
        assert (labels[outside] == nusc.lidarseg_name2idx_mapping["flat.driveable_surface"]).all()
    assert in_boxes > 0
