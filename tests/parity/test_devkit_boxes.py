"""nuparquet.devkit's box calls against nuscenes-devkit: get_sample_data (every box_vis_level, selected_anntokens,
use_flat_vehicle_coordinates), get_boxes, get_box and box_velocity give the same boxes with the same numbers, bit
for bit (centre, size, orientation quaternion, label, score, velocity, name, token), in the same order."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from devkit_pairs import box_values, open_pair
from devkit_same import assert_same
from conftest import SYNTH_VERSION
from nuparquet.devkit import NuScenes
from nuparquet.devkit.utils.geometry_utils import BoxVisibility

VARIANTS = ({}, {"box_vis_level": BoxVisibility.ALL}, {"box_vis_level": BoxVisibility.NONE},
            {"use_flat_vehicle_coordinates": True},
            {"box_vis_level": BoxVisibility.NONE, "use_flat_vehicle_coordinates": True})


@pytest.fixture(scope="module", params=["synth", "irregular", "layouts", "labelled"])
def pair(request, devkit):
    return open_pair(request, devkit, request.param)


@pytest.fixture(scope="module")
def extract(request, devkit):
    return open_pair(request, devkit, "extract")


def assert_sample_data_equal(pair, token: str, **kwargs) -> int:
    theirs = pair.theirs.get_sample_data(token, **kwargs)
    ours = pair.ours.get_sample_data(token, **kwargs)
    assert_same([ours[0], [box_values(b) for b in ours[1]], ours[2]],
                [theirs[0], [box_values(b) for b in theirs[1]], theirs[2]], f"get_sample_data({token}, {kwargs})")
    assert all(type(b).__module__ == "nuparquet.devkit.utils.data_classes" for b in ours[1])
    return len(theirs[1])


def test_get_sample_data_of_every_frame_equals_the_devkits_at_every_visibility_level(pair):
    """Keyframes with every variant, sweeps with one each (in turn)."""
    counts = {"kept": 0, "dropped": 0}
    for i, record in enumerate(pair.theirs.sample_data):
        for kwargs in VARIANTS if record["is_key_frame"] else (VARIANTS[i % len(VARIANTS)],):
            kept = assert_sample_data_equal(pair, record["token"], **kwargs)
            if record["sensor_modality"] == "camera" and record["is_key_frame"]:
                if not kwargs:
                    counts["kept"] += kept
                elif kwargs == {"box_vis_level": BoxVisibility.NONE}:
                    counts["dropped"] += kept
    counts["dropped"] -= counts["kept"]
    assert counts["kept"] > 0 and counts["dropped"] > counts["kept"], counts  # the visibility test decides both ways


def test_get_sample_data_of_selected_annotations_equals_the_devkits(pair):
    for sample in pair.theirs.sample[::3]:
        selected = sample["anns"][::2]
        for token in sample["data"].values():
            assert_sample_data_equal(pair, token, selected_anntokens=selected)
            assert_sample_data_equal(pair, token, selected_anntokens=selected, box_vis_level=BoxVisibility.ALL)


def test_get_boxes_of_every_frame_equals_the_devkits_interpolated_sweep_boxes_included(pair):
    interpolated = 0
    for record in pair.theirs.sample_data:
        theirs = pair.theirs.get_boxes(record["token"])
        assert_same([box_values(b) for b in pair.ours.get_boxes(record["token"])], [box_values(b) for b in theirs])
        interpolated += sum(not any(np.array_equal(b.center, pair.theirs.get("sample_annotation", b.token)["translation"])
                                    for _ in [0]) for b in theirs)
    assert interpolated > 0 or not len(pair.theirs.sample_annotation)


def test_get_box_and_box_velocity_of_every_annotation_equal_the_devkits(pair):
    nan_velocities = 0
    for record in pair.theirs.sample_annotation:
        token = record["token"]
        assert_same(box_values(pair.ours.get_box(token)), box_values(pair.theirs.get_box(token)))
        for max_time_diff in (1.5, 0.3):
            theirs = pair.theirs.box_velocity(token, max_time_diff)
            assert_same(pair.ours.box_velocity(token, max_time_diff), theirs)
            nan_velocities += bool(np.isnan(theirs).any())
    assert nan_velocities > 0 or not len(pair.theirs.sample_annotation)


def test_real_extract_keyframes_and_one_cameras_sweeps_equal_the_devkits(extract):
    kept = 0
    for sample in extract.theirs.sample:
        for channel, token in sample["data"].items():
            kept += assert_sample_data_equal(extract, token)
            if channel in ("CAM_FRONT", "LIDAR_TOP") and sample["timestamp"] % 3 == 0:
                for kwargs in VARIANTS[1:]:
                    assert_sample_data_equal(extract, token, **kwargs)
    sweeps = [r["token"] for r in extract.theirs.sample_data if r["channel"] == "CAM_BACK" and not r["is_key_frame"]]
    for token in sweeps[::4]:
        assert_sample_data_equal(extract, token)
        assert_same([box_values(b) for b in extract.ours.get_boxes(token)],
                    [box_values(b) for b in extract.theirs.get_boxes(token)])
    for record in extract.theirs.sample_annotation[::7]:
        assert_same(extract.ours.box_velocity(record["token"]), extract.theirs.box_velocity(record["token"]))
    assert kept > 1000 and len(sweeps) > 200


def test_an_unknown_visibility_level_is_a_value_error_for_a_camera_as_in_the_devkit(extract):
    camera = extract.theirs.sample[10]["data"]["CAM_FRONT"]
    for nusc in (extract.theirs, extract.ours):
        with pytest.raises(ValueError, match="vis_level: 7 not valid"):
            nusc.get_sample_data(camera, box_vis_level=7)
    lidar = extract.theirs.sample[10]["data"]["LIDAR_TOP"]
    assert_sample_data_equal(extract, lidar, box_vis_level=7)  # not a camera: the level is not looked at


def test_samples_sharing_a_timestamp_fail_in_a_sweep_as_in_the_devkit(layouts_root, tmp_path, devkit):
    """The devkit divides by the two samples' time difference; nuparquet raises the same ZeroDivisionError,
    saying which samples and what interpolates them (frame_boxes)."""
    from nuparquet.conversion import convert

    root = tmp_path / "data"
    shutil.copytree(layouts_root / SYNTH_VERSION, root / SYNTH_VERSION)
    (root / "maps").symlink_to(layouts_root / "maps", target_is_directory=True)  # the devkit asserts they exist
    samples = json.loads((root / SYNTH_VERSION / "sample.json").read_text())
    by_token = {s["token"]: s for s in samples}
    tied = next(s for s in samples if s["prev"] and by_token[s["prev"]]["prev"])
    tied["timestamp"] = by_token[tied["prev"]]["timestamp"]
    (root / SYNTH_VERSION / "sample.json").write_text(json.dumps(samples))
    convert(root, SYNTH_VERSION, tmp_path / "out")
    theirs = devkit.NuScenes(SYNTH_VERSION, dataroot=str(root), verbose=False)
    ours = NuScenes(SYNTH_VERSION, dataroot=str(root), parquet=tmp_path / "out", verbose=False)
    sweep = next(r["token"] for r in theirs.sample_data if r["sample_token"] == tied["token"] and not r["is_key_frame"])
    with pytest.raises(ZeroDivisionError):
        theirs.get_boxes(sweep)
    with pytest.raises(ZeroDivisionError, match=f"{tied['prev']}.*{tied['token']}.*frame_boxes"):
        ours.get_boxes(sweep)
    keyframe = theirs.get("sample", tied["token"])["data"]["CAM_FRONT"]
    assert_same([box_values(b) for b in ours.get_boxes(keyframe)], [box_values(b) for b in theirs.get_boxes(keyframe)])


def test_a_version_without_annotations_gives_the_devkits_empty_boxes(request, devkit):
    pair = open_pair(request, devkit, "irregular_empty")
    assert not len(pair.theirs.sample_annotation)
    for record in pair.theirs.sample_data[::5]:
        for kwargs in VARIANTS:
            assert assert_sample_data_equal(pair, record["token"], **kwargs) == 0
        assert pair.ours.get_boxes(record["token"]) == pair.theirs.get_boxes(record["token"]) == []


def test_sweeps_stamped_outside_their_two_samples_are_clamped_to_them_as_in_the_devkit(tiny_map_root, tmp_path,
                                                                                        devkit):
    """The devkit's get_boxes clamps a sweep's time into [previous sample, its sample] ("timestamps in the DB are
    off"): a lidar sweep edited to lie 30 ms past its sample gets that sample's boxes as annotated, one edited to lie
    30 ms before the previous sample gets the previous sample's; nuparquet's get_boxes and get_sample_data equal the
    devkit's, where extrapolating (amount above 1 or below 0) would move every interpolated box."""
    from types import SimpleNamespace

    from nuparquet.conversion import convert

    root = tmp_path / "data"
    shutil.copytree(tiny_map_root / SYNTH_VERSION, root / SYNTH_VERSION)
    (root / "maps").symlink_to(tiny_map_root / "maps", target_is_directory=True)  # the devkit asserts they exist
    path = root / SYNTH_VERSION / "sample_data.json"
    records = json.loads(path.read_text())
    samples = {s["token"]: s for s in json.loads((root / SYNTH_VERSION / "sample.json").read_text())}
    sweeps = [r for r in records if not r["is_key_frame"] and "LIDAR_TOP" in r["filename"]
              and samples[r["sample_token"]]["prev"]]
    late, early = sweeps[0], sweeps[-1]
    current = samples[late["sample_token"]]
    late["timestamp"] = current["timestamp"] + 30_000
    previous = samples[samples[early["sample_token"]]["prev"]]
    early["timestamp"] = previous["timestamp"] - 30_000
    path.write_text(json.dumps(records))
    convert(root, SYNTH_VERSION, tmp_path / "out")
    theirs = devkit.NuScenes(SYNTH_VERSION, dataroot=str(root), verbose=False)
    ours = NuScenes(SYNTH_VERSION, dataroot=str(root), parquet=tmp_path / "out", verbose=False)
    pair = SimpleNamespace(ours=ours, theirs=theirs)
    for sweep, clamped_to in ((late, current), (early, previous)):
        boxes = theirs.get_boxes(sweep["token"])
        assert_same([box_values(b) for b in ours.get_boxes(sweep["token"])], [box_values(b) for b in boxes])
        assert_sample_data_equal(pair, sweep["token"], box_vis_level=BoxVisibility.NONE)
        # the clamp is reached: the boxes (interpolated between the two samples' annotations of one instance) sit
        # exactly on the annotations of the sample the time is clamped to
        annotations = [theirs.get("sample_annotation", a) for a in theirs.get("sample", clamped_to["token"])["anns"]]
        on = {a["instance_token"]: a["translation"] for a in annotations}
        instance = [theirs.get("sample_annotation", b.token)["instance_token"] for b in boxes]
        both = [(b, on[i]) for b, i in zip(boxes, instance) if i in on]
        assert len(both) > 0 and all(np.allclose(b.center, centre, rtol=0, atol=1e-9) for b, centre in both)
