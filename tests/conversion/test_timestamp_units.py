"""Timestamps in the wrong unit (nanoseconds, milliseconds, seconds instead of microseconds): validate names the
field, the range and the likely unit; the data converts as it is, and stats and sql print it without crashing."""

from __future__ import annotations

import json
import shutil

import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main

V = SYNTH_VERSION


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    from nuparquet.synth import synthesize

    root = tmp_path_factory.mktemp("units") / "data"
    synthesize(root, scenes=1, samples_per_scene=3, seed=2, version=V, with_can_bus=False)
    return root


@pytest.mark.parametrize("unit, rescale", [("nanoseconds", lambda t: t * 1000), ("milliseconds", lambda t: t // 1000),
                                           ("seconds", lambda t: t // 1_000_000)])
def test_wrong_units_are_named_and_nothing_crashes(pristine, tmp_path, capsys, unit, rescale):
    root = tmp_path / "data"
    shutil.copytree(pristine / V, root / V)
    for table in ("sample", "sample_data", "ego_pose"):
        path = root / V / f"{table}.json"
        records = json.loads(path.read_text())
        for r in records:
            r["timestamp"] = rescale(r["timestamp"])
        path.write_text(json.dumps(records))
    assert main(["validate", str(root), "--version", V, "--quiet"]) == 0
    out = capsys.readouterr().out
    for table in ("sample", "sample_data", "ego_pose"):
        assert f"warning: {table}.json: timestamp values" in out and f"look like {unit}" in out
    out_dir = tmp_path / "out"
    assert main(["convert", str(root), "--version", V, "--out", str(out_dir), "--quiet"]) == 0
    assert "look like" in capsys.readouterr().err
    for fmt in ("table", "csv", "json"):
        assert main(["stats", str(out_dir), "--format", fmt]) == 0
    assert main(["sql", str(out_dir), "SELECT min(time_utc) AS t, max(timestamp) AS m FROM frames"]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err


def test_plausible_microseconds_give_no_warning(pristine, capsys):
    assert main(["validate", str(pristine), "--version", V, "--quiet"]) == 0
    assert "warning" not in capsys.readouterr().out


def test_the_unit_guess_at_its_limits():
    """Plausible microseconds lie in [2000, 2100); beyond, the most telling end of the range (the high one when it
    is too high) is classed: > 100x the upper limit nanoseconds, between 1e-5 and 1e-2 of the lower limit
    milliseconds, below 1e-5 of it seconds, anything else another unit. Each message is a warning."""
    import polars as pl

    from nuparquet.sources.integrity import PLAUSIBLE_TIMESTAMP_US, _timestamp_units

    low, high = PLAUSIBLE_TIMESTAMP_US
    cases = {
        "ns": ([low + 1, high * 100 + 1], "nanoseconds"),  # only the high end is wrong: it decides
        "ms": ([low // 100 - 1, low // 100 - 1], "milliseconds"),
        "s": ([low // 100_000 - 1, low // 100_000 - 1], "seconds"),
        "other": ([500_000_000_000_000, 500_000_000_000_000], "another unit"),  # half the lower limit
        # the bounds themselves belong to neither class: exactly 1e-5 and 1e-2 of the lower limit
        "s_bound": ([low // 100_000, low // 100_000], "another unit"),
        "ms_bound": ([low // 100, low // 100], "another unit"),
        "fine": ([low, high], None),
    }
    frames = {name: pl.DataFrame({"timestamp": values}) for name, (values, _) in cases.items()}
    warnings = _timestamp_units(frames, {name: f"{name}.json" for name in cases})
    got = {w.file: w for w in warnings}
    assert set(got) == {f"{name}.json" for name, (_, unit) in cases.items() if unit}
    for name, (values, unit) in cases.items():
        if unit:
            assert got[f"{name}.json"].warning
            assert got[f"{name}.json"].message == (f"timestamp values {values[0]:g}..{values[1]:g} are not microseconds "
                                                   f"between 2000 and 2100 (they look like {unit}); converted as they are")
