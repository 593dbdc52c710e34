"""The mosaic's choice of camera frames against the devkit itself: `NuScenesExplorer.render_scene` is run on
the irregular synthetic dataset (frames on the 10 Hz clock ticks, a CAM_FRONT whose first frame comes 250 ms
after the first sample, the last time step past the last sample) with its window calls stubbed out, recording
which frame of each camera every output shows. The keyframe mosaic is checked against the devkit's sample walk."""

from __future__ import annotations

import os

import numpy as np
import pytest

import nuparquet
from nuparquet.rendering.plan import camera_rows_per_output
from nuparquet.rendering.video.scene import load_scene
from conftest import IRREGULAR_VERSION

os.environ.setdefault("MPLBACKEND", "Agg")  # the devkit's explorer imports pyplot; never open a window

DEVKIT_LAYOUT = ("CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_BACK_LEFT", "CAM_BACK", "CAM_BACK_RIGHT")


@pytest.fixture(scope="module")
def nusc(devkit, irregular_root):
    return devkit.NuScenes(version=IRREGULAR_VERSION, dataroot=str(irregular_root), verbose=False)


class _HeadlessCv2:
    """What render_scene calls on cv2, without a window: imshow records the frames on the canvas."""

    def __init__(self, shown: dict, steps: list):
        self._shown, self._steps = shown, steps

    def namedWindow(self, *args): pass  # noqa: E704, N802
    def moveWindow(self, *args): pass  # noqa: E704, N802
    def destroyAllWindows(self): pass  # noqa: E704, N802
    def waitKey(self, *args): return -1  # noqa: E704, N802
    def imread(self, path): return np.zeros((1, 1, 3), np.uint8)  # noqa: E704
    def resize(self, image, size): return np.zeros((size[1], size[0], 3), np.uint8)  # noqa: E704
    def imshow(self, name, canvas): self._steps.append(dict(self._shown))  # noqa: E704


def devkit_render_scene_frames(nusc, monkeypatch, scene_token: str, freq_hz: float) -> list[dict[str, str]]:
    """Per output of devkit render_scene: channel -> sample_data token on the canvas."""
    import nuscenes.nuscenes as devkit_module

    shown, steps = {}, []
    channel_of = {sd["token"]: sd["channel"] for sd in nusc.sample_data}

    def get_sample_data(token, box_vis_level=None):
        shown[channel_of[token]] = token
        return nusc.get_sample_data_path(token), [], np.eye(3)

    monkeypatch.setattr(devkit_module, "cv2", _HeadlessCv2(shown, steps))
    monkeypatch.setattr(nusc, "get_sample_data", get_sample_data)
    nusc.explorer.render_scene(scene_token, freq=freq_hz, imsize=(16, 9))
    monkeypatch.undo()
    return steps


def ours(out, scene_name: str, *, all_frames: bool, fps: float) -> tuple[np.ndarray, list[dict[str, str]]]:
    loaded = load_scene(nuparquet.open(out), scene_name, list(DEVKIT_LAYOUT), all_frames=all_frames)
    times, rows = camera_rows_per_output(loaded.cameras, loaded.samples, DEVKIT_LAYOUT, mosaic=True,
                                         all_frames=all_frames, fps=fps)
    tokens = loaded.cameras["token"].to_list()
    return times, [{c: tokens[r] for c, r in zip(DEVKIT_LAYOUT, row) if r >= 0} for row in rows]


@pytest.mark.devkit
@pytest.mark.parametrize("freq_hz", [10.0, 12.0, 2.0])
def test_all_frames_mosaic_shows_what_devkit_render_scene_shows(nusc, irregular_out, monkeypatch, freq_hz):
    ties = late = 0
    for scene in nusc.scene:
        expected = devkit_render_scene_frames(nusc, monkeypatch, scene["token"], freq_hz)
        times, got = ours(irregular_out, scene["name"], all_frames=True, fps=freq_hz)
        assert len(got) == len(expected), scene["name"]  # the last step included, none after it
        assert got == expected, scene["name"]
        stamp = {sd["token"]: sd["timestamp"] for sd in nusc.sample_data}
        ties += sum(stamp[token] == t for t, step in zip(times, got) for token in step.values())
        first = nusc.get("sample", scene["first_sample_token"])
        front = nusc.get("sample_data", first["data"]["CAM_FRONT"])
        late += front["timestamp"] > times[0]  # the first output shows a frame from after it
        assert got[-1] == {c: _last_frame(nusc, first["data"][c]) for c in DEVKIT_LAYOUT}
    if freq_hz == 10.0:
        assert ties > 10  # frames exactly on a clock step were compared
        assert late == 1


def _last_frame(nusc, token: str) -> str:
    while nusc.get("sample_data", token)["next"]:
        token = nusc.get("sample_data", token)["next"]
    return token


@pytest.mark.devkit
def test_keyframe_mosaic_shows_each_samples_keyframes_in_time_order(nusc, irregular_out):
    for scene in nusc.scene:
        expected, token = [], scene["first_sample_token"]
        while token:  # the devkit's sample chain: one output per sample, each camera's keyframe
            sample = nusc.get("sample", token)
            expected.append({c: sample["data"][c] for c in DEVKIT_LAYOUT})
            token = sample["next"]
        times, got = ours(irregular_out, scene["name"], all_frames=False, fps=2.0)
        assert got == expected
        assert (np.diff(times) > 0).all()
