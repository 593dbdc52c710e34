"""The stats section registry: sections whose datasets were not converted stay out of the default run, and
asking for one explicitly is a usage error naming the missing dataset."""

from __future__ import annotations

import polars as pl
import pytest

import nuparquet
from nuparquet.errors import UsageError
from nuparquet.queries import sections


@pytest.fixture
def with_can_section(monkeypatch):
    extra = sections.Section("can_speed", "CAN speed", lambda ds, scene, o: pl.LazyFrame({"x": [1]}),
                             requires=("sample_can_bus",))
    monkeypatch.setattr(sections, "SECTIONS", sections.SECTIONS + (extra,))
    monkeypatch.setitem(sections.BY_NAME, "can_speed", extra)
    return extra


def test_default_sections_skip_sections_whose_datasets_are_absent(synth_out, with_can_section):
    ds = nuparquet.open(synth_out)
    assert "can_speed" not in sections.default_sections(ds)
    assert "can_speed" in sections.default_sections(None)  # no dataset given: every default section
    assert set(sections.summary(ds)) == set(sections.default_sections(ds))


def test_a_requested_section_without_its_dataset_is_a_usage_error(synth_out, with_can_section):
    with pytest.raises(UsageError, match="can_speed needs dataset.*sample_can_bus"):
        sections.summary(nuparquet.open(synth_out), sections=["scenes", "can_speed"])


def test_bin_width_reaches_the_distance_histogram(synth_out):
    ds = nuparquet.open(synth_out)
    for width in (5.0, 20.0):
        hist = sections.summary(ds, sections=["distance_histogram"], bin_width_m=width)["distance_histogram"].collect()
        assert ((hist["bin_end_m"] - hist["bin_start_m"]) == width).all()
