"""nuparquet.devkit's printers against nuscenes-devkit's: list_categories, list_attributes, list_scenes, list_sample,
list_lidarseg_categories, list_panoptic_instances and get_sample_lidarseg_stats print the same text (the devkit's
own timing aside), the labels read from the converted lidar points or from the label files."""

from __future__ import annotations

import contextlib
import io
import re

import pytest

from devkit_pairs import open_pair
from conftest import SYNTH_VERSION
from nuparquet.devkit import NuScenes

SORTS = ("count", "name", "index")


def printed(function, *args, **kwargs) -> str:
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        function(*args, **kwargs)
    return re.sub(r"in \d+\.\d seconds", "in X seconds", buffer.getvalue())  # the devkit prints its time


@pytest.fixture(scope="module", params=["synth", "irregular", "irregular_empty", "layouts", "labelled", "extract"])
def pair(request, devkit):
    return open_pair(request, devkit, request.param)


def test_listings_print_what_the_devkits_print(pair):
    for name in ("list_categories", "list_attributes", "list_scenes"):
        ours = printed(getattr(pair.ours, name))
        assert ours == printed(getattr(pair.theirs, name)), name
        assert ours.strip() or name != "list_scenes"
    for sample in pair.theirs.sample[::4]:
        assert printed(pair.ours.list_sample, sample["token"]) == printed(pair.theirs.list_sample, sample["token"])
    assert printed(pair.ours.explorer.list_categories) == printed(pair.theirs.explorer.list_categories)


@pytest.fixture(scope="module")
def labelled_without_label_files(labelled_root, tmp_path_factory):
    """The labelled dataroot without its lidarseg/ and panoptic/ folders: labels must come from the Parquet."""
    root = tmp_path_factory.mktemp("no-labels") / "data"
    root.mkdir()
    for entry in labelled_root.iterdir():
        if entry.name not in ("lidarseg", "panoptic"):
            (root / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    return root


@pytest.mark.parametrize("labels_from", ["files", "parquet"])
def test_label_statistics_print_what_the_devkits_print(labelled_root, labelled_out, labelled_without_label_files,
                                                       devkit, tmp_path, labels_from):
    theirs = devkit.NuScenes(SYNTH_VERSION, dataroot=str(labelled_root), verbose=False)
    if labels_from == "files":  # a conversion without lidar_points: the label files under the dataroot
        from nuparquet.conversion import convert

        convert(labelled_root, SYNTH_VERSION, tmp_path / "out")
        ours = NuScenes(SYNTH_VERSION, dataroot=str(labelled_root), parquet=tmp_path / "out", verbose=False)
        assert "lidar_points" not in ours._dataset.datasets
    else:
        ours = NuScenes(SYNTH_VERSION, dataroot=str(labelled_without_label_files), parquet=labelled_out, verbose=False)
    samples = [s["token"] for s in theirs.sample[::2]]
    for sort_by in SORTS:
        for gt_from in ("lidarseg", "panoptic"):
            expected = printed(theirs.list_lidarseg_categories, sort_by=sort_by, gt_from=gt_from)
            assert printed(ours.list_lidarseg_categories, sort_by=sort_by, gt_from=gt_from) == expected
            for sample in samples:
                expected = printed(theirs.get_sample_lidarseg_stats, sample, sort_by=sort_by, gt_from=gt_from)
                assert printed(ours.get_sample_lidarseg_stats, sample, sort_by=sort_by, gt_from=gt_from) == expected
                assert expected.count("\n") > 3
        for get_hist in (False, True):
            expected = printed(theirs.list_panoptic_instances, sort_by=sort_by, get_hist=get_hist)
            assert printed(ours.list_panoptic_instances, sort_by=sort_by, get_hist=get_hist) == expected
            assert "instances, each instance spans" in expected
    # an unknown sort_by: the devkit's assertion, word for word
    for call in ("list_lidarseg_categories", "list_panoptic_instances"):
        messages = []
        for nusc in (ours, theirs):
            with pytest.raises(AssertionError) as raised:
                getattr(nusc, call)(sort_by="size")
            messages.append(str(raised.value))
        assert messages[0] == messages[1] and "sort_by can only be" in messages[0], call
    messages = []
    for nusc in (ours, theirs):
        with pytest.raises(AssertionError) as raised:
            nusc.get_sample_lidarseg_stats(samples[0], sort_by="size")
        messages.append(str(raised.value))
    assert messages[0] == messages[1] and "sort_by can only be" in messages[0]


def test_lidarseg_statistics_of_a_prediction_file_print_what_the_devkits_print(labelled_root, labelled_out, devkit,
                                                                               tmp_path):
    import numpy as np

    theirs = devkit.NuScenes(SYNTH_VERSION, dataroot=str(labelled_root), verbose=False)
    ours = NuScenes(SYNTH_VERSION, dataroot=str(labelled_root), parquet=labelled_out, verbose=False)
    sample = theirs.sample[1]
    points = len(np.fromfile(theirs.get_sample_data_path(sample["data"]["LIDAR_TOP"]), dtype=np.float32)) // 5
    predictions = tmp_path / "predictions.bin"
    np.random.default_rng(0).integers(0, 32, points).astype(np.uint8).tofile(predictions)
    expected = printed(theirs.get_sample_lidarseg_stats, sample["token"], lidarseg_preds_bin_path=str(predictions))
    assert "(predictions)" in expected
    assert printed(ours.get_sample_lidarseg_stats, sample["token"], lidarseg_preds_bin_path=str(predictions)) == expected
    # the explorer's own method, with every default (sort_by count, the lidarseg ground truth), as the devkit's call
    expected = printed(theirs.get_sample_lidarseg_stats, sample["token"])
    assert "(predictions)" not in expected and expected.count("\n") > 3
    assert printed(ours.explorer.sample_lidarseg_stats, sample["token"]) == expected
