"""The reports the report tests read: the synthetic dataset (2 scenes, points, CAN bus for scene-0001 only, map)
built once per session."""

from __future__ import annotations

import pytest

from nuparquet.engine import EngineOptions
from nuparquet.report import ReportOptions, build_report


@pytest.fixture(scope="session")
def synth_report(synth_points_out, tmp_path_factory):
    """The report of every scene of `synth_points_out`, videos and keyframe renderings included (one process)."""
    out = tmp_path_factory.mktemp("report") / "report"
    events = []
    result = build_report(synth_points_out, ReportOptions(out=out), EngineOptions(engine="serial"),
                          on_progress=events.append)
    return result, events


@pytest.fixture(scope="session")
def real_report(extract_out, tmp_path_factory):
    """The report of the real extract's two scenes (keyframe images only: the sweeps are absent)."""
    out = tmp_path_factory.mktemp("report-real") / "report"
    return build_report(extract_out, ReportOptions(out=out, video_scale=0.2, stills=2), EngineOptions(engine="serial"))


@pytest.fixture(scope="session")
def six_scene_report(map_out, tmp_path_factory):
    """A report without videos of the 6-scene, 4-location synthetic dataset (tables only): the table to sort."""
    out = tmp_path_factory.mktemp("report-six") / "report"
    return build_report(map_out, ReportOptions(out=out, videos=False), EngineOptions(engine="serial"))
