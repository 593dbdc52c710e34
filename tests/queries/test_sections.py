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
