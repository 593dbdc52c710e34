"""The render job's seams: progress events for the caller, and CLI flags generated from `RenderOptions`."""

from __future__ import annotations

import argparse
import dataclasses

import nuparquet
from nuparquet.cli import render as render_cli
from nuparquet.cli.arguments import options_from
from nuparquet.engine import EngineOptions
from nuparquet.dataset.selection import SceneSelection
from nuparquet.rendering.video.options import RenderOptions
from nuparquet.rendering.video.pipeline import render


def test_render_reports_one_frame_per_output_picture(synth_out, tmp_path):
    scene = nuparquet.open(synth_out).scan("scenes").select("name").collect()["name"].sort()[0]
    events = []
    result = render(synth_out, scene, tmp_path / "x.mp4", RenderOptions(scale=0.1), on_progress=events.append)
    assert result.channel == "CAM_FRONT"  # the default camera, chosen from the data
    assert {e.task for e in events} == {f"render {scene} CAM_FRONT"} and {e.unit for e in events} == {"frame"}
    assert [e.done for e in events if not e.finished] == list(range(result.frames_written + 1))
    assert events[-1].finished and events[-1].total == result.frames_written
    assert all(not e.finished for e in events[:-1])


def test_every_cli_render_option_is_a_flag_with_the_library_default():
    parser = argparse.ArgumentParser()
    render_cli.register(parser.add_subparsers())
    args = parser.parse_args(["render", "OUT", "--scene", "s1"])
    defaults = options_from(args, RenderOptions, unset=("scale",))
    assert defaults == RenderOptions() and args.scene == "s1"
    assert args.out is None and args.frames_dir is None and args.out_dir is None and args.dataroot is None
    flags = ["--channel", "all", "--out", "v.mp4", "--frames-dir", "d", "--frame-format", "png", "--all-frames",
             "--fps", "3", "--scale", "0.3", "--crf", "30", "--lidar", "--labels", "track", "--clip",
             "--on-missing", "error", "--dataroot", "root"]
    parsed = parser.parse_args(["render", "OUT", "--scene", "s1", *flags])
    given = options_from(parsed, RenderOptions, unset=("scale",))
    assert given == RenderOptions(channel="all", frame_format="png", all_frames=True, fps=3.0, scale=0.3, crf=30,
                                  lidar=True, labels="track", clip=True, on_missing="error")
    assert (parsed.out, parsed.frames_dir, parsed.dataroot) == ("v.mp4", "d", "root")  # targets and inputs
    # Every field is either a flag or explicitly library-only; the other flags choose scenes and the engine, or
    # what one picture draws, or say where to write and where the sensor files are.
    from nuparquet.rendering.pictures.image_options import ImageOptions
    from nuparquet.sensors.options import SensorFiles

    flagged = {f.name for option_class in (RenderOptions, SceneSelection, EngineOptions, ImageOptions, SensorFiles)
               for f in dataclasses.fields(option_class) if f.metadata["cli"]}
    assert flagged == {a.dest for a in parser._subparsers._group_actions[0].choices["render"]._actions} - {
        "help", "dataset", "scene", "quiet", "out", "frames_dir", "out_dir"}
    assert options_from(args, SceneSelection) == SceneSelection() and options_from(args, EngineOptions) == EngineOptions()
    assert options_from(args, ImageOptions, unset=("scale",), labels="none") == ImageOptions()
    assert not ImageOptions().wanted and ImageOptions().scale is None  # one picture: its own full size by default


def test_render_scenes_takes_engine_fields_as_keywords_and_writes_one_video_per_scene(synth_root, synth_out, tmp_path):
    """The many-scene render as a notebook calls it (selection, render and engine options as keyword fields): a
    video per scene holding one frame per CAM_FRONT keyframe of the scene (counted in the JSON tables); `out` is
    refused (the files are DIR/<scene>.mp4)."""
    import json

    import av
    import pytest

    from nuparquet.errors import UsageError

    table = {name: json.loads((synth_root / "v1.0-synth" / f"{name}.json").read_text())
             for name in ("scene", "sample", "sample_data", "calibrated_sensor", "sensor")}
    scene = min(s["name"] for s in table["scene"])
    scene_token = next(s["token"] for s in table["scene"] if s["name"] == scene)
    front = {c["token"] for c in table["calibrated_sensor"]
             if next(s["channel"] for s in table["sensor"] if s["token"] == c["sensor_token"]) == "CAM_FRONT"}
    samples = {s["token"] for s in table["sample"] if s["scene_token"] == scene_token}
    keyframes = sum(d["is_key_frame"] and d["sample_token"] in samples and d["calibrated_sensor_token"] in front
                    for d in table["sample_data"])
    result = nuparquet.render_scenes(synth_out, None, tmp_path / "videos", scenes=[scene], scale=0.1,
                                     keep_going=True, engine=EngineOptions(engine="serial"))
    assert result.written == [scene] and sorted(p.name for p in (tmp_path / "videos").glob("*.mp4")) == [f"{scene}.mp4"]
    with av.open(str(tmp_path / "videos" / f"{scene}.mp4")) as video:
        assert keyframes > 1 and sum(1 for _ in video.decode(video=0)) == keyframes
    with pytest.raises(UsageError, match="--all-scenes, --scenes and --where write one file per scene: give --out-dir"):
        nuparquet.render_scenes(synth_out, nuparquet.SceneSelection(scenes=(scene,)), None, workers=1)
    with pytest.raises(TypeError, match="unknown option.*out_dir"):  # where it writes is the argument, not a field
        nuparquet.render_scenes(synth_out, None, tmp_path / "x", scenes=[scene], out_dir=tmp_path / "x")
