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
def labelled(tmp_path_factory):
    from nuparquet.convert import convert
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path_factory.mktemp("labelled-q") / "data", scenes=2, samples_per_scene=4, with_lidar=True,
                      seed=5, version=SYNTH_VERSION, with_can_bus=False)
    out = tmp_path_factory.mktemp("labelled-q-out") / "out"
    convert(root, SYNTH_VERSION, out, sensors=("lidar",), jobs=1)
    return root, out


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
    assert ours["sample_token"].n_unique() == len(nusc.sample) == 8
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


def test_points_in_boxes_equal_num_lidar_pts_on_synthetic_data(ds, nusc):
    from nuparquet.queries.points import points_in_boxes

    counts = points_in_boxes(ds)
    assert counts.height == len(nusc.sample_annotation)
    assert counts["points_in_box"].to_list() == counts["num_lidar_pts"].to_list()
    assert counts["points_in_box"].sum() > 0


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
