"""`annotations.file_index` and `instances.file_index` are the devkit's list indices (`nusc.sample_annotation[i]`,
`nusc.instance[i]`), and a sample's annotations ordered by it are the devkit's `sample['anns']`: a tutorial's
`my_sample['anns'][18]` or `nusc.instance[599]` can be found in the derived datasets, which are sorted by scene
and time (issue 24)."""

from __future__ import annotations

import polars as pl
import pytest

import nuparquet
from conftest import EXTRACT_VERSION, SYNTH_VERSION


@pytest.fixture(scope="module", params=["synth", "extract"])
def case(request, devkit):
    if request.param == "synth":
        root, out, version = request.getfixturevalue("synth_root"), request.getfixturevalue("synth_out"), SYNTH_VERSION
    else:
        root, out, version = request.getfixturevalue("extract_root"), request.getfixturevalue("extract_out"), EXTRACT_VERSION
    return nuparquet.open(out), devkit.NuScenes(version, str(root), verbose=False)


def test_annotation_file_index_is_the_devkit_list_index(case):
    ds, nusc = case
    annotations = ds.scan("annotations").select("token", "file_index").collect().sort("file_index")
    assert annotations["file_index"].to_list() == list(range(len(nusc.sample_annotation)))
    assert annotations["token"].to_list() == [a["token"] for a in nusc.sample_annotation]
    # the derived dataset is not in file order: the column is what finds a devkit index
    stored = ds.scan("annotations").select("token").collect()["token"].to_list()
    assert stored != annotations["token"].to_list()


def test_a_samples_annotations_by_file_index_are_its_anns(case):
    ds, nusc = case
    by_sample = (ds.scan("annotations").sort("file_index").group_by("sample_token", maintain_order=True)
                 .agg(pl.col("token")).collect())
    anns = dict(zip(by_sample["sample_token"].to_list(), by_sample["token"].to_list()))
    for sample in nusc.sample:
        assert anns.get(sample["token"], []) == sample["anns"]


def test_instance_file_index_is_the_devkit_list_index(case):
    ds, nusc = case
    instances = ds.scan("instances").select("token", "file_index").collect().sort("file_index")
    assert instances["token"].to_list() == [i["token"] for i in nusc.instance]
