"""The stats section registry: sections whose datasets were not converted stay out of the default run, and
asking for one explicitly is a usage error naming the missing dataset."""

from __future__ import annotations

import polars as pl
import pytest

import nuparquet
from nuparquet.errors import UsageError
from nuparquet.queries import sections


@pytest.fixture
def with_unavailable_section(monkeypatch):
    extra = sections.Section("fake_section", "a section of an unconverted dataset", lambda ds, scene, o: pl.LazyFrame({"x": [1]}),
                             requires=("not_converted_dataset",))
    monkeypatch.setattr(sections, "SECTIONS", sections.SECTIONS + (extra,))
    monkeypatch.setitem(sections.BY_NAME, "fake_section", extra)
    return extra


def test_default_sections_skip_sections_whose_datasets_are_absent(synth_out, with_unavailable_section):
    ds = nuparquet.open(synth_out)
    assert "fake_section" not in sections.default_sections(ds)
    assert "fake_section" in sections.default_sections(None)  # no dataset given: every default section
    assert set(sections.summary(ds)) == set(sections.default_sections(ds))


def test_a_requested_section_without_its_dataset_is_a_usage_error(synth_out, with_unavailable_section):
    with pytest.raises(UsageError, match="fake_section needs dataset.*not_converted_dataset"):
        sections.summary(nuparquet.open(synth_out), sections=["scenes", "fake_section"])


def test_bin_width_reaches_the_distance_histogram(synth_out):
    ds = nuparquet.open(synth_out)
    for width in (5.0, 20.0):
        hist = sections.summary(ds, sections=["distance_histogram"], bin_width_m=width)["distance_histogram"].collect()
        assert ((hist["bin_end_m"] - hist["bin_start_m"]) == width).all()


@pytest.fixture(scope="module")
def unlabelled_points_out(tmp_path_factory):
    """lidar_points/ converted from a dataroot whose lidarseg and panoptic labels were removed."""
    import shutil

    from conftest import SYNTH_VERSION
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path_factory.mktemp("unlabelled") / "data", scenes=1, samples_per_scene=2, with_lidar=True,
                      seed=2, version=SYNTH_VERSION, with_can_bus=False)
    for extension in ("lidarseg", "panoptic"):
        shutil.rmtree(root / extension)
        (root / SYNTH_VERSION / f"{extension}.json").unlink()
    out = tmp_path_factory.mktemp("unlabelled-out") / "out"
    nuparquet.convert(root, SYNTH_VERSION, out, sensors=("lidar",), workers=1)
    return out


@pytest.mark.parametrize("section", ["lidarseg", "panoptic"])
def test_asking_for_label_sections_without_labels_says_there_are_none(unlabelled_points_out, section, capsys):
    from nuparquet.cli.main import main

    ds = nuparquet.open(unlabelled_points_out)
    assert section not in sections.default_sections(ds)
    with pytest.raises(UsageError, match=f"section {section}: lidar_points/ holds no {section} labels"):
        sections.summary(ds, sections=[section])
    assert main(["stats", str(unlabelled_points_out), "--only", section]) == 2
    captured = capsys.readouterr()
    assert f"no {section} labels" in captured.err and "points" not in captured.out
